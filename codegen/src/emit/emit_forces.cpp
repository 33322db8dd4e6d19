// The header's force functions: ForceCode prints solve_forces and force_columns from the
// symbolic stage's force model (emit_header's order is in emit_cpp.cpp).
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "printer.hpp"
#include "sections.hpp"

namespace kinegen::codegen::emit_detail {

namespace {

// ---- Kinetostatics (symbolic/forces.hpp): Phi_q^T lambda = Q after a step.

// Whether the mechanism carries anything for the force functions: a mass, an inertia or a
// load (gravity alone acts on nothing).
bool has_force_data(const ForceModel& f) {
  for (std::size_t b = 0; b < f.symbolic.mass.size(); ++b)
    if (!f.symbolic.mass[b].is_zero() || !f.symbolic.inertia[b].is_zero()) return true;
  for (const auto& e : f.applied)
    if (!e.is_zero()) return true;
  return false;
}

// The force functions' code, built from the mechanism's force model: the geometry they read
// (one program), the inertia forces per body and the force columns, as text.
class ForceCode {
 public:
  ForceCode(const CompiledModel& compiled, const EmitOptions& options, ForceModel f,
            const std::vector<int>& trig_slot)
      : compiled_(compiled),
        m_(compiled.mechanism()),
        symbols_(compiled.symbols()),
        model_(compiled.symbolic()),
        options_(options),
        f_(std::move(f)),
        names_(force_columns(m_)),
        trig_slot_(trig_slot),
        mass_at_(m_.bodies.size(), -1) {
    const Mechanism& m = m_;
    const ModelPrograms& programs = compiled.programs();
    for (std::size_t e = 0; e < programs.jac_rows.size(); ++e)
      entry_[{programs.jac_rows[e], programs.jac_cols[e]}] = static_cast<int>(e);
    for (int b = 0; b < static_cast<int>(m.bodies.size()); ++b) add_inertia(b);
    const int nj = static_cast<int>(m.joints.size());
    for (std::size_t d = 0; d < m.drivers.size(); ++d)
      if (!m.drivers[d].free) add_driver_columns(m.drivers[d], nj + static_cast<int>(d));
    for (int j = 0; j < nj; ++j)
      if (!is_expression(m.joints[j])) add_joint_columns(m.joints[j], j);
  }

  // generalized_force, solve_forces and force_columns, with applied_force and the private
  // _force_geometry they share.
  void print(std::ostringstream& os) const {
    const std::shared_ptr<const ForcePrograms> programs = compiled_.force_programs(f_);
    const Program& applied_program = programs->applied;
    std::vector<GiNaC::ex> geometry = geometry_;
    if (geometry.empty()) geometry.push_back(0);  // out[1], so that the function reads `out`
    // What the printed columns read, built with their text here (the analysis computes the
    // same geometry in double, forces.hpp): the one program the emitter lowers itself.
    const Program geometry_program = lower(geometry, symbols_);
    const std::string ng = idx(static_cast<int>(geometry.size()));
    std::vector<std::string> quoted;
    for (const auto& n : names_) quoted.push_back("\"" + n + "\"");
    const int max_ops = options_.max_function_ops;

    os << "\n  // ---- Kinetostatics: driver efforts and joint reactions\n"
       << "  // of the motion from M qdd + Phi_q^T lambda = Q^A, i.e. Phi_q^T lambda = Q with\n"
       << "  // Q = Q^A + the inertia forces, solved through the blocks in reverse order. Usable\n"
       << "  // straight after solve_step at the same t (feedforward efforts).\n"
       << "  static constexpr bool has_forces = true;\n"
       << "  // The columns of `kinegen analyze --forces`, in its order: each driver's effort(s),\n"
       << "  // each joint's fx, fy (global) and tz about its point.\n"
       << "  static constexpr int num_force_columns = " << names_.size() << ";\n"
       << "  static constexpr std::array<const char*, num_force_columns> force_column_names = {"
       << join(quoted) << "};\n\n"
       << "  // Q^A(q, qd, t): gravity and the loads (forces, torques, spring-dampers).\n";
    emit_function(os, "applied_force", "nq", applied_program, symbols_, true, max_ops);
    os << "\n private:\n"
       << "  // What the force functions read besides Phi_q: per body with mass or inertia m, J "
          "and\n"
       << "  // A com; per distance driver its length; per joint the offset A s of its point.\n";
    emit_function(os, "_force_geometry", ng.c_str(), geometry_program, symbols_, false, max_ops);
    os << "\n public:\n"
       << "  // Q = Q^A + the inertia forces of the motion: -m a_com at each centre of mass\n"
       << "  // (with the omega^2 term of an offset centre) and -J alpha. out[nq].\n"
       << "  template <class T>\n"
       << "  static void generalized_force(const T* q, const T* qd, [[maybe_unused]] const T* "
          "qdd,\n"
       << "                                T t, const Params& p, T* out) noexcept {\n"
       << "    applied_force(q, qd, t, p, out);\n"
       << "    T g[" << ng << "];\n"
       << "    _force_geometry(q, t, p, g);\n"
       << inertia_.str() << "  }\n\n"
       << "  // Phi_q^T lambda = Q (generalized_force) at a solved q, qd, qdd, in reverse\n"
       << "  // block order. lambda[nc]. factors: nullptr, and each block is factored again\n"
       << "  // (one LU per block), or those solve_step kept at this q and t (its last\n"
       << "  // argument), and nothing is factored again: the feedforward efforts after a\n"
       << "  // step. Fails with status 2 (a singular or ill-conditioned block: a toggle\n"
       << "  // position, where the efforts grow without bound) or 3 (not finite) and the\n"
       << "  // block; report.rcond is the smallest block's, with factors the step's (below\n"
       << "  // options.min_rcond every block is factored and checked).\n"
       << "  template <class T, class U>\n"
       << "  static BlockReport<_real<T>> solve_forces(const T* q, const T* qd, const T* qdd, T "
          "t,\n"
       << "      const Params& p, T* lambda, const BasicBlockOptions<U>& options,\n"
       << "      const StepFactors<T>* factors = nullptr) noexcept {\n"
       << "    T jac[jac_nnz], b[nq];\n"
       << "    phi_q(q, t, p, jac);\n"
       << "    generalized_force(q, qd, qdd, t, p, b);\n"
       << "    return _block_transposed_reusing<_model>(jac, b, lambda, factors,\n"
       << "                                             _options_as<_real<T>>(options));\n"
       << "  }\n\n"
       << "  // The force_column_names columns from lambda (solve_forces) at the same q and t. "
          "The\n"
       << "  // reaction on the bodies is -Phi_q^T lambda; an effort is positive when it pushes "
          "its\n"
       << "  // driven quantity up. out[num_force_columns].\n"
       << "  template <class T>\n"
       << "  static void force_columns(const T* q, T t, const Params& p, const T* lambda,\n"
       << "                            T* out) noexcept {\n"
       << "    T jac[jac_nnz], g[" << ng << "];\n"
       << "    phi_q(q, t, p, jac);\n"
       << "    _force_geometry(q, t, p, g);\n"
       << columns_.str() << "  }\n";
    if (!m_.free_drivers().empty())
      emit_dynamics(os, {compiled_, m_, symbols_, model_, f_, options_, mass_at_,
                         static_cast<int>(geometry.size()), trig_slot_});
  }

 private:
  GiNaC::ex fold(const GiNaC::ex& e) const {
    return compiled_.build_options().fold_params
               ? substitute_params(e, symbols_, model_.param_values)
               : e;
  }
  // A s: a body-fixed offset in global axes (ground: s itself).
  std::array<GiNaC::ex, 2> rotated(int body, const std::array<GiNaC::ex, 2>& s) const {
    if (body == kGround) return {fold(s[0]), fold(s[1])};
    const GiNaC::ex phi = symbols_.q(3 * body + 2);
    return {fold(cos(phi) * s[0] - sin(phi) * s[1]), fold(sin(phi) * s[0] + cos(phi) * s[1])};
  }
  // r + A s: a body-fixed point in global coordinates.
  std::array<GiNaC::ex, 2> at(int body, const std::array<GiNaC::ex, 2>& s) const {
    auto a = rotated(body, s);
    if (body != kGround) {
      a[0] += symbols_.q(3 * body);
      a[1] += symbols_.q(3 * body + 1);
    }
    return a;
  }
  // g[k] in the functions' text: the geometry value k.
  static std::string g(int k) { return "g[" + idx(k) + "]"; }
  // -Phi_q^T lambda of constraint c at coordinate k, as text ("" when it has no entry there).
  std::string reaction(int c, int k) const {
    std::string s;
    for (int r = f_.row_begin[c]; r < f_.row_begin[c + 1]; ++r)
      if (const auto it = entry_.find({r, k}); it != entry_.end())
        s += " - jac[" + idx(it->second) + "] * lambda[" + idx(r) + "]";
    return s.empty() ? std::string() : "-" + s.substr(3);
  }

  // A body with mass or inertia: its m, J and A com in the geometry, and -m a_com, -J alpha,
  // as add_inertia_forces (analysis/forces.hpp) computes them.
  void add_inertia(int b) {
    const GiNaC::ex mass = fold(f_.symbolic.mass[b]), j = fold(f_.symbolic.inertia[b]);
    if (mass.is_zero() && j.is_zero()) return;
    const int g0 = static_cast<int>(geometry_.size());
    mass_at_[b] = g0;
    const auto a = rotated(b, f_.symbolic.com[b]);
    for (const GiNaC::ex& e : {mass, j, a[0], a[1]}) geometry_.push_back(e);
    const std::string x = idx(3 * b), y = idx(3 * b + 1), phi = idx(3 * b + 2);
    inertia_ << "    {  // body '" << m_.bodies[b].name
             << "': a_com = rdd + alpha (A com)^perp - omega^2 A com\n"
             << "      const T w = qd[" << phi << "], wd = qdd[" << phi << "];\n"
             << "      const T fx = -" << g(g0) << " * (qdd[" << x << "] - wd * " << g(g0 + 3)
             << " - w * w * " << g(g0 + 2) << ");\n"
             << "      const T fy = -" << g(g0) << " * (qdd[" << y << "] + wd * " << g(g0 + 2)
             << " - w * w * " << g(g0 + 3) << ");\n"
             << "      out[" << x << "] += fx;\n      out[" << y << "] += fy;\n"
             << "      out[" << phi << "] += " << g(g0 + 2) << " * fy - " << g(g0 + 3) << " * fx - "
             << g(g0 + 1) << " * wd;\n    }\n";
  }

  // A driver's effort column(s), as columns_from_lambda computes them.
  void add_driver_columns(const Constraint& c, int k) {
    const int r0 = f_.row_begin[k];
    if (is_distance(c)) {
      // Phi = d.d - f^2: the force along d is -lambda dPhi/dL = -2 lambda L.
      const auto pj = at(c.j, f_.symbolic.sj[k]), pi = at(c.i, f_.symbolic.si[k]);
      const GiNaC::ex dx = pj[0] - pi[0], dy = pj[1] - pi[1];
      columns_ << "    out[" << col_ << "] = T(-2) * lambda[" << r0 << "] * g[" << geometry_.size()
               << "];  // " << names_[col_] << "\n";
      geometry_.push_back(fold(sqrt(dx * dx + dy * dy)));
      ++col_;
    } else {
      for (int r = r0; r < f_.row_begin[k + 1]; ++r, ++col_)
        columns_ << "    out[" << col_ << "] = -lambda[" << r << "];  // " << names_[col_] << "\n";
    }
  }

  // A joint's fx, fy and tz about its point (and J.fn of a cam contact), as
  // columns_from_lambda computes them.
  void add_joint_columns(const Constraint& c, int jn) {
    const bool on_j = c.j != kGround;
    const int body = on_j ? c.j : c.i;
    const auto a = rotated(body, on_j ? f_.symbolic.sj[jn] : f_.symbolic.si[jn]);
    const std::string ax = g(static_cast<int>(geometry_.size())),
                      ay = g(static_cast<int>(geometry_.size()) + 1);
    geometry_.push_back(a[0]);
    geometry_.push_back(a[1]);
    const std::string name = names_[col_].substr(0, names_[col_].size() - 3);
    const auto or_zero = [](const std::string& s) { return s.empty() ? "T(0)" : s; };
    const std::string tz = reaction(jn, 3 * body + 2);
    columns_ << "    {  // " << name << " on body '" << m_.bodies[body].name << "'\n"
             << "      const T fx = " << or_zero(reaction(jn, 3 * body)) << ";\n"
             << "      const T fy = " << or_zero(reaction(jn, 3 * body + 1)) << ";\n"
             << "      out[" << col_ << "] = fx;\n      out[" << col_ + 1 << "] = fy;\n"
             << "      out[" << col_ + 2 << "] = " << (tz.empty() ? "-(" : tz + " - (") << ax
             << " * fy - " << ay << " * fx);  // about the point\n";
    if (c.kind->normal_force) {
      // J.fn as normal_force (analysis/forces.hpp): t = A_i curve_i'(a) = -d(contact rows)/da.
      const int a = m_.coordinate_index(c.coordinates.at("coordinate_i")), r0 = f_.row_begin[jn];
      const auto minus_jac = [&](int r) {
        const auto it = entry_.find({r, a});
        return it == entry_.end() ? std::string("T(0)") : "-jac[" + idx(it->second) + "]";
      };
      columns_ << "      using std::sqrt;\n"
               << "      const T tx = " << minus_jac(r0) << ", ty = " << minus_jac(r0 + 1) << ";\n"
               << "      out[" << col_ + 3 << "] = (" << (on_j ? "fx" : "-fx") << " * ty - "
               << (on_j ? "fy" : "-fy") << " * tx) / sqrt(tx * tx + ty * ty);  // normal force\n";
    }
    columns_ << "    }\n";
    col_ += 3 + static_cast<int>(c.kind->normal_force);
  }

  const CompiledModel& compiled_;
  const Mechanism& m_;
  const SymbolTable& symbols_;
  const SymbolicModel& model_;
  const EmitOptions& options_;
  const ForceModel f_;
  const std::vector<std::string> names_;  // force_columns(m)
  const std::vector<int>& trig_slot_;
  std::map<std::pair<int, int>, int> entry_;  // Phi_q's (row, column) -> entry
  // What the functions read besides Phi_q: per body with mass or inertia m, J and A com; per
  // distance driver its length; per joint with columns the global offset A s of its point.
  std::vector<GiNaC::ex> geometry_;
  std::vector<int> mass_at_;  // per body: its m, J, A com in the geometry (-1: none)
  std::ostringstream inertia_, columns_;
  int col_ = 0;  // the next force column
};

}  // namespace

// The force functions, when the mechanism has masses, inertias or loads. Masses, inertias,
// centres of mass and the joints' points are read from Params like the rest of the header
// (constants with --fold-params). The inertia forces and the columns follow add_inertia_forces
// and columns_from_lambda, the analysis' numeric templates (analysis/forces.hpp), printed
// instead of evaluated.
void emit_forces(std::ostringstream& os, const CompiledModel& compiled, const EmitOptions& options,
                 const std::vector<int>& trig_slot) {
  const Mechanism& m = compiled.mechanism();
  if (m.forces.loads.empty() && m.forces.bodies.empty()) return;
  if (!has_force_data(compiled.forces())) return;
  ForceCode(compiled, options, compiled.forces(), trig_slot).print(os);
}

}  // namespace kinegen::codegen::emit_detail

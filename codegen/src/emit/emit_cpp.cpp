#include "kinegen/codegen/emit/emit_cpp.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>

#include "block_solver.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/emit/embedded_kernels.hpp"
#include "kinegen/codegen/emit/reserved_names.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/program/partition.hpp"
#include "kinegen/codegen/structure/block_program.hpp"
#include "kinegen/codegen/structure/solver_plan.hpp"
#include "kinegen/codegen/structure/structure.hpp"
#include "printer.hpp"
#include "sections.hpp"

namespace kinegen::codegen {

using namespace emit_detail;  // the stage's printer and block solver

namespace {

// ---- Header layout: the kernels, tables, structure tables, sensitivities, forces, outputs and
// the block solver's functions (block_solver.cpp) in one self-contained header.

// The block-solver kernels (runtime/include/kinegen/kernels/, embedded at build time) that
// `code` calls, with those they call, in dependency order: each pasted unchanged between marker
// comments (tests/test_kernels.cpp compares them with the files).
// with_linear: the block-linear kernels even where `code` calls none (a spatial file's first
// solve runs on them: kinegen/driver_continuation.hpp).
void emit_kernels(std::ostringstream& os, const std::string& code, bool with_linear) {
  const auto calls = [&](const char* name) { return code.find(name) != std::string::npos; };
  const bool trig = calls("_trig(");
  const bool rotation = trig || calls("_rotate(");
  const bool lu = calls("_lu_factor<") || calls("_sdirk2_step<");
  const bool newton = calls("_newton_end(");
  const bool linear = with_linear || calls("_block_forward<") || calls("_block_transposed<") ||
                      calls("_block_transposed_reusing<");
  const bool tangent = calls("_dynamics_tangent<");
  const bool dynamics = tangent || calls("_reduced_accelerations(");
  for (const auto& k : embedded::kKernels) {
    const std::string name = k.name;
    const bool used = name == "report" || (name == "lu" && (lu || linear)) ||
                      (name == "block_linear" && linear) || (name == "rotation" && rotation) ||
                      (name == "trig_cache" && trig) || (name == "newton" && newton) ||
                      (name == "dynamics" && dynamics) || (name == "linearize" && tangent) ||
                      (name == "integrate" && calls("_rk4_step<"));
    if (!used) continue;
    os << "  // ---- kinegen kernel " << name << " (kinegen/kernels/" << name << ".hpp)\n"
       << k.text << "  // ---- end of kinegen kernel " << name << "\n\n";
  }
}

// The knots of each table a header reads, as constant arrays, and its function `_tblK(order,
// x)` over the spline kernel; the tokens renamed to `_tblK` in order of first use.
std::string with_tables(std::string& header, std::size_t at) {
  std::string data;
  int next = 0;
  for (std::size_t p = header.find("_tbl@", at); p != std::string::npos;
       p = header.find("_tbl@", at)) {
    const std::size_t end = header.find('@', p + 5);
    const std::string token = header.substr(p, end + 1 - p);
    const Spline& s = registered_table(std::stoi(token.substr(5)));
    const std::string name = "_tbl" + std::to_string(next++);
    for (std::size_t q = header.find(token); q != std::string::npos; q = header.find(token, q))
      header.replace(q, token.size(), name);
    const auto array = [&](const char* suffix, const std::vector<double>& v) {
      std::string line =
          "  static constexpr double " + name + suffix + "[" + std::to_string(v.size()) + "] = {";
      for (std::size_t k = 0; k < v.size(); ++k) line += (k ? ", " : "") + format_double(v[k]);
      return line + "};\n";
    };
    data += "  // Table " + std::to_string(next - 1) +
            (s.periodic ? " (periodic, period " + format_double(s.period) + ")" : "") +
            ": knots, values" + (s.periodic ? " less the trend" : "") +
            " and the spline's second derivatives (not extrapolated: NaN outside)\n";
    data += array("_t", s.t) + array("_y", s.y) + array("_m", s.m);
    data += "  template <class T>\n  static T " + name + "(int order, const T& x) noexcept {\n" +
            "    return _table(" + name + "_t, " + name + "_y, " + name + "_m, " +
            std::to_string(s.t.size()) + ", double(" + format_double(s.periodic ? s.period : 0.0) +
            "), double(" + format_double(s.rise) + "), order, x);\n  }\n\n";
  }
  return data;
}

// The kernels that expressions call (motion laws, pieces, tables), pasted at `at` (before the
// first function) once the whole header is written, so that every function that calls one
// counts.
std::string with_expression_kernels(std::string header, std::size_t at) {
  const std::string tables = with_tables(header, at);
  const bool uses[] = {header.find("_motion_law(", at) != std::string::npos,
                       header.find("_select(", at) != std::string::npos ||
                           header.find("_floor_re(", at) != std::string::npos,
                       !tables.empty()};
  const char* names[] = {"motion_law", "piecewise", "spline"};
  std::string text;
  for (int u = 0; u < 3; ++u) {
    if (!uses[u]) continue;
    for (const auto& k : embedded::kKernels) {
      if (std::string(k.name) != names[u]) continue;
      text += std::string("  // ---- kinegen kernel ") + names[u] + " (kinegen/kernels/" +
              names[u] + ".hpp)\n" + k.text + "  // ---- end of kinegen kernel " + names[u] +
              "\n\n";
    }
  }
  header.insert(at, text + tables);
  return header;
}

// The block-linear kernel keeps a K x K matrix per block on the stack and instantiates its LU
// for every size up to the largest block; beyond this size the linear solves after a position
// solve (sensitivities, forces) are not generated.
constexpr int kMaxLinearBlock = 16;

bool linear_blocks_supported(const Structure& st) {
  return st.order.perfect && !st.plans.empty() && st.largest_block() <= kMaxLinearBlock;
}

// The structure tables the block_linear kernel reads (kernels/block_linear.hpp).
void emit_structure_tables(std::ostringstream& os, const std::string& name, const Structure& st,
                           const ModelPrograms& programs) {
  std::vector<std::string> begin{"0"}, rows, cols, block(programs.nq), slot(programs.nq);
  std::vector<std::string> factor_begin{"0"};
  std::size_t factors = 0;
  for (std::size_t k = 0; k < st.order.blocks.size(); ++k) {
    const Block& b = st.order.blocks[k];
    factors += b.cols.size() * b.cols.size();
    factor_begin.push_back(std::to_string(factors));
    for (std::size_t i = 0; i < b.cols.size(); ++i) {
      block[b.cols[i]] = std::to_string(k);
      slot[b.cols[i]] = std::to_string(cols.size());
      rows.push_back(std::to_string(b.rows[i]));
      cols.push_back(std::to_string(b.cols[i]));
    }
    begin.push_back(std::to_string(cols.size()));
  }
  std::vector<std::string> row_begin;
  std::size_t e = 0;
  for (int r = 0; r <= programs.nc; ++r) {
    while (e < programs.jac_rows.size() && programs.jac_rows[e] < r) ++e;
    row_begin.push_back(std::to_string(e));
  }
  for (std::size_t k = 1; k < programs.jac_rows.size(); ++k)
    if (programs.jac_rows[k] < programs.jac_rows[k - 1])
      throw std::logic_error("emit_structure_tables: Phi_q entries are not sorted by row");
  os << "  // The block structure as tables, for the linear solves with Phi_q after a position\n"
     << "  // solve (kinegen/kernels/block_linear.hpp): each block's rows and coordinates in "
        "solve\n"
     << "  // order, each coordinate's block and place, each row's first Phi_q entry.\n"
     << "  static constexpr std::array<int, num_blocks + 1> block_begin = {" << join(begin)
     << "};\n"
     << "  static constexpr std::array<int, nc> block_rows = {" << join(rows) << "};\n"
     << "  static constexpr std::array<int, nq> block_cols = {" << join(cols) << "};\n"
     << "  static constexpr std::array<int, nq> coordinate_block = {" << join(block) << "};\n"
     << "  static constexpr std::array<int, nq> coordinate_slot = {" << join(slot) << "};\n"
     << "  static constexpr std::array<int, nc + 1> jac_row_begin = {" << join(row_begin) << "};\n"
     << "  // Where each block's K x K factors start when all are kept (_block_factor_all).\n"
     << "  static constexpr std::array<int, num_blocks + 1> block_factor_begin = {"
     << join(factor_begin)
     << "};\n"
     // The kernel's S, named so that a function parameter named like the model (q, options)
     // cannot hide it; no model's name starts with '_'.
     << "  using _model = " << name << ";\n\n";
}

}  // namespace

// The mechanism's outputs: values, rates, and accelerations as O_q qdd plus the
// rest, from the programs the analysis runs. Nothing for a file without outputs. Where an
// output reads velocities, output_values also takes qd, output_rates adds O_qd, and that
// output's velocity is the rate plus O_qd qdd and its acceleration nan (it would need the
// jerk); a file without such outputs keeps the header it had.
void emit_outputs(std::ostringstream& os, const Mechanism& m, const SymbolTable& symbols,
                  const ModelPrograms& programs, int max_ops) {
  const int n = programs.num_outputs;
  const auto& reads = programs.output_reads_velocity;
  const bool velocities = std::find(reads.begin(), reads.end(), true) != reads.end();
  os << "\n  // Outputs (in this order):";
  for (int o = 0; o < n; ++o) os << (o ? "," : "") << " " << m.outputs[o].name;
  os << ".\n  static constexpr int num_outputs = " << n << ";\n";
  if (velocities) {
    os << "  // Outputs that read velocities (their acceleration is nan):";
    for (int o = 0; o < n; ++o)
      if (reads[o]) os << " " << m.outputs[o].name;
    os << ".\n  // Output values O(q, qd, t)\n";
  } else {
    os << "  // Output values O(q, t)\n";
  }
  emit_function(os, "output_values", "num_outputs", programs.outputs, symbols, velocities, max_ops);
  const char* rates_size = velocities ? "num_outputs * (2 + 2 * nq)" : "num_outputs * (2 + nq)";
  os << "\n  // Rates O_q qd + O_t, then accelerations at qdd = 0, then O_q (row-major)"
     << (velocities ? ", then O_qd (row-major)" : "") << "\n";
  emit_function(os, "output_rates", rates_size, programs.output_rates, symbols, true, max_ops);
  os << "\n  // Value, velocity and acceleration of each output at a solved q, qd, qdd\n"
     << "  // (exact time derivatives along the motion).\n"
     << "  template <class T>\n"
     << "  static void outputs(const T* q, const T* qd, const T* qdd, T t, const Params& p, "
        "T* value,\n"
     << "                      T* velocity, T* acceleration) noexcept {\n"
     << "    std::array<T, " << rates_size << "> r;\n"
     << "    output_values(q, " << (velocities ? "qd, " : "") << "t, p, value);\n"
     << "    output_rates(q, qd, t, p, r.data());\n";
  if (velocities) {
    os << "    constexpr bool reads_velocity[num_outputs] = {";
    for (int o = 0; o < n; ++o) os << (o ? ", " : "") << (reads[o] ? "true" : "false");
    os << "};\n"
       << "    for (int o = 0; o < num_outputs; ++o) {\n"
       << "      if (reads_velocity[o]) {\n"
       << "        T v = r[o];\n"
       << "        for (int k = 0; k < nq; ++k) v += r[(2 + nq) * num_outputs + o * nq + k] * "
          "qdd[k];\n"
       << "        velocity[o] = v;\n"
       << "        acceleration[o] = T(std::numeric_limits<double>::quiet_NaN());\n"
       << "        continue;\n"
       << "      }\n";
  } else {
    os << "    for (int o = 0; o < num_outputs; ++o) {\n";
  }
  os << "      velocity[o] = r[o];\n"
     << "      T a = r[num_outputs + o];\n"
     << "      for (int k = 0; k < nq; ++k) a += r[2 * num_outputs + o * nq + k] * qdd[k];\n"
     << "      acceleration[o] = a;\n"
     << "    }\n"
     << "  }\n";
}

namespace {

// What --outputs asks for: nu (velocity) and gamma (acceleration) besides phi and phi_q.
bool has_velocity(const EmitOptions& options) { return options.outputs != Outputs::kPosition; }
bool has_acceleration(const EmitOptions& options) { return options.outputs == Outputs::kAll; }

// The banner (where the file came from, "do not edit", the command that regenerates it), the
// standard headers and the opening of the namespace.
void emit_banner(std::ostringstream& os, const Mechanism& m, const EmitOptions& options,
                 bool folded) {
  std::string base = m.source;
  if (const auto slash = base.find_last_of("/\\"); slash != std::string::npos)
    base = base.substr(slash + 1);
  base = safe_comment_text(base);

  os << "// Generated by kinegen " << kVersion << " from " << base << ". Do not edit.\n"
     << "// Regenerate with: kinegen generate " << base << " -o <dir>"
     << (options.outputs == Outputs::kPosition   ? " --outputs position"
         : options.outputs == Outputs::kVelocity ? " --outputs velocity"
                                                 : "")
     << (folded ? " --fold-params" : "") << "\n";
  if (folded)
    os << "// Parameters folded into constants (--fold-params): Params is kept for the same "
          "API, but its members are ignored.\n";
  os << "//\n"
     << (m.spatial ? "// Spatial Cartesian kinematics (Euler parameters, one normalization row per "
                     "body)\n// of mechanism '"
                   : "// Planar Cartesian kinematics of mechanism '")
     << m.name << "': Phi(q, t) = 0 with\n"
     << "// nu = -Phi_t and gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt.\n"
     << "#pragma once\n\n#include <algorithm>\n#include <array>\n#include <cmath>\n#include "
        "<cstring>\n#include <limits>\n#include <type_traits>\n#include <utility>\n\n"
     << "namespace " << options.name_space << " {\n\n";
}

// The coordinates and constraint rows as comments, then the struct's constant tables: sizes,
// Phi_q's pattern, q0, the length scale, the coordinates' kinds and scales.
void emit_model_tables(std::ostringstream& os, const Mechanism& m, const SymbolTable& symbols,
                       const SymbolicModel& model, const ModelPrograms& programs) {
  os << "// Coordinates:";
  // A line per body, then one for the extra coordinates.
  const int per_body = m.spatial ? 7 : 3;
  const int body_coordinates = per_body * static_cast<int>(m.bodies.size());
  for (int k = 0; k < programs.nq; ++k)
    os << ((k < body_coordinates ? k % per_body == 0 : k == body_coordinates) ? "\n//  " : ",")
       << " q[" << k << "] = " << symbols.coord_name(k);
  os << "\n// Constraint rows:\n";
  for (int r = 0; r < programs.nc; ++r) {
    const Constraint* c = model.rows[r].constraint;
    if (model.rows[r].component > 0) continue;
    const int n = c->equation_count();
    // c->item is built from validated names and the constraint type only.
    os << "//   "
       << (n == 1 ? std::to_string(r) : std::to_string(r) + "-" + std::to_string(r + n - 1)) << ": "
       << c->item << "\n";
  }
  os << "struct " << m.name << " {\n";
  os << "  static constexpr int nq = " << programs.nq << ";\n";
  os << "  static constexpr int nc = " << programs.nc << ";\n";
  os << "  static constexpr int jac_nnz = " << programs.jac_rows.size() << ";\n";
  std::vector<std::string> rows, cols, q0;
  for (int r : programs.jac_rows) rows.push_back(std::to_string(r));
  for (int c : programs.jac_cols) cols.push_back(std::to_string(c));
  for (const auto& e : model.q0)
    q0.push_back(format_double(to_double(substitute_params(e, symbols, model.param_values))));
  os << "  static constexpr std::array<int, jac_nnz> jac_rows = {" << join(rows) << "};\n";
  os << "  static constexpr std::array<int, jac_nnz> jac_cols = {" << join(cols) << "};\n";
  os << "  // Initial estimates for the first position solve, from the mechanism file.\n";
  os << "  static constexpr std::array<double, nq> q0 = {" << join(q0) << "};\n";
  os << "  // A typical length of the mechanism; position tolerances scale with it.\n";
  os << "  static constexpr double length_scale = " << format_double(model.length_scale) << ";\n";
  {
    std::vector<std::string> kinds, scales;
    for (std::size_t k = 0; k < model.coordinate_kinds.size(); ++k) {
      kinds.push_back(std::to_string(static_cast<int>(model.coordinate_kinds[k])));
      scales.push_back(format_double(model.coordinate_scales[k]));
    }
    os << "  // What each coordinate measures (kinegen::CoordinateKind: 0 length, 1 angle, 2 "
          "scalar)\n"
       << "  // and the size its tolerances scale with (a body's x and y: its joints' geometry).\n"
       << "  static constexpr std::array<int, nq> coordinate_kinds = {" << join(kinds) << "};\n"
       << "  static constexpr std::array<double, nq> coordinate_scales = {" << join(scales)
       << "};\n\n";
  }
}

// Params: each parameter with its value from the file, and an input driver's members.
void emit_params(std::ostringstream& os, const Mechanism& m, const SymbolTable& symbols,
                 const SymbolicModel& model, bool folded) {
  os << "  struct Params {\n";
  if (folded)
    os << "    // Ignored: these values were folded into the code at generation.\n";
  for (int k = 0; k < symbols.num_params(); ++k)
    os << "    double " << symbols.param_name(k) << " = "
       << format_double(model.param_values[k].to_double()) << ";\n";
  for (std::size_t d = 0; d < m.drivers.size(); ++d) {
    if (!m.drivers[d].law.input) continue;
    const int k = static_cast<int>(d);
    os << "    // " << (m.drivers[d].free ? "Free item " : "Input driver ") << m.drivers[d].name
       << (m.drivers[d].free ? " (free:)" : " (f: input)")
       << ": its value, rate and acceleration, set at run time\n"
       << "    double " << input_member(m, k, 0) << " = 0, " << input_member(m, k, 1) << " = 0, "
       << input_member(m, k, 2) << " = 0;\n";
  }
  for (const Load::Input* in : m.load_inputs())
    if (in->table_id < 0)
      os << "    double " << in->name << " = 0;  // a load's input, set at run time\n";
  if (!m.free_drivers().empty())
    os << "    // Leave null: dynamics() points it at its z, zd and zdd (T[3 nf]) while it runs,\n"
       << "    // which the functions then read instead of the free items' members above.\n"
       << "    const void* _free = nullptr;\n";
  os << "  };\n\n";
  if (!m.free_drivers().empty()) {
    // Every member but _free, for dynamics_jacobians' reuse of a dynamics() at the same point.
    std::vector<std::string> same;
    const auto member = [&](const std::string& name) {
      same.push_back("_same_bits(a." + name + ", b." + name + ")");
    };
    for (int k = 0; k < symbols.num_params(); ++k) member(symbols.param_name(k));
    for (std::size_t d = 0; d < m.drivers.size(); ++d)
      if (m.drivers[d].law.input)
        for (int order = 0; order < 3; ++order) member(input_member(m, static_cast<int>(d), order));
    for (const Load::Input* in : m.load_inputs())
      if (in->table_id < 0) member(in->name);
    os << "  // Whether a and b hold the same values (_same_bits: -0.0 and 0.0 apart).\n"
       << "  static bool _same_params([[maybe_unused]] const Params& a,\n"
       << "                           [[maybe_unused]] const Params& b) noexcept {\n"
       << "    return " << (same.empty() ? std::string("true") : "");
    for (std::size_t i = 0; i < same.size(); ++i)
      os << (i == 0 ? "" : " &&\n           ") << same[i];
    os << ";\n  }\n\n";
  }
  if (!m.free_drivers().empty())
    os << "  // A free item's value (i < nf), rate or acceleration, as dynamics() set it.\n"
       << "  template <class T>\n"
       << "  static T _free_in(const Params& p, int i, double member) noexcept {\n"
       << "    return p._free ? static_cast<const T*>(p._free)[i] : T(member);\n"
       << "  }\n\n";
}

// The section-4 functions phi, phi_q, nu and gamma (as many as --outputs asks for), repeated
// constraints rolled into loops over tables.
void emit_constraint_functions(std::ostringstream& os, const SymbolTable& symbols,
                               const SymbolicModel& model, const ModelPrograms& programs,
                               const EmitOptions& options) {
  const bool velocity = has_velocity(options), acceleration = has_acceleration(options);
  // Each output's constraint, for repeated constraints (roll_outputs).
  const std::vector<int> row_group = constraint_groups(model);
  std::vector<int> entry_group;
  std::vector<GiNaC::ex> jac;
  for (const auto& e : model.phi_q) {
    entry_group.push_back(row_group[e.row]);
    jac.push_back(e.value);
  }
  const int max_ops = options.max_function_ops, roll_min = options.roll_min;
  os << "  // Phi(q, t)\n";
  emit_function_rolled_if(os, "phi", "nc", programs.phi, model.phi, row_group, symbols, false,
                          max_ops, roll_min);
  os << "\n  // Phi_q(q, t) at (jac_rows[k], jac_cols[k])\n";
  emit_function_rolled_if(os, "phi_q", "jac_nnz", programs.phi_q, jac, entry_group, symbols, false,
                          max_ops, roll_min);
  if (velocity) {
    os << "\n  // nu = -Phi_t\n";
    emit_function_rolled_if(os, "nu", "nc", programs.nu, model.nu, row_group, symbols, false,
                            max_ops, roll_min);
  }
  if (acceleration) {
    os << "\n  // gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt\n";
    emit_function_rolled_if(os, "gamma", "nc", programs.gamma, model.gamma, row_group, symbols,
                            true, max_ops, roll_min);
  }
}

// Which of the section-4 functions the header has.
void emit_output_flags(std::ostringstream& os, const EmitOptions& options) {
  const bool velocity = has_velocity(options), acceleration = has_acceleration(options);
  os << "\n  // Which outputs were generated (kinegen generate --outputs).\n";
  os << "  static constexpr bool has_velocity = " << (velocity ? "true" : "false") << ";\n";
  os << "  static constexpr bool has_acceleration = " << (acceleration ? "true" : "false") << ";\n";
}

// The coordinates Newton iterates (num_newton_coordinates, newton_coordinates).
void emit_newton_coordinates(std::ostringstream& os, const Structure& st) {
  std::vector<std::string> iterated;
  for (const BlockPlan& plan : st.plans)
    if (plan.kind == BlockKind::kNewton)
      for (int c : plan.torn() ? plan.tears : plan.block.cols) iterated.push_back(idx(c));
  os << "  // The coordinates Newton iterates; the block solver computes the others from them, "
        "so\n"
     << "  // only these need a good start (a predictor).\n"
     << "  static constexpr int num_newton_coordinates = " << iterated.size() << ";\n"
     << "  static constexpr std::array<int, num_newton_coordinates> newton_coordinates = {"
     << join(iterated) << "};\n";
}

// The block solver: its structure constants; then the tables the linear solves read, the kernels
// that the functions below call and nothing else, the sin/cos cache type, and the functions:
// the step's factors, the block functions printed from the solver plan, and the linear solves
// that reuse its blocks (sensitivities, forces).
void emit_block_solver(std::ostringstream& os, const CompiledModel& compiled, const Structure& st,
                       const EmitOptions& options) {
  const Mechanism& m = compiled.mechanism();
  const SymbolTable& symbols = compiled.symbols();
  const SymbolicModel& model = compiled.symbolic();
  const bool velocity = has_velocity(options), acceleration = has_acceleration(options);
  os << "\n  // Block solver: Phi(q, t) = 0 in block-lower-triangular order (maximum matching, "
        "then\n"
     << "  // strongly connected components). Each block reads only its own and earlier blocks'\n"
     << "  // coordinates.\n";
  os << "  static constexpr bool has_block_solver = " << (st.order.perfect ? "true" : "false")
     << ";\n";
  os << "  static constexpr int num_blocks = " << st.plans.size() << ";\n";
  if (st.order.perfect) {
    os << "  static constexpr int num_explicit_blocks = " << st.explicit_count() << ";\n";
    os << "  static constexpr int max_block_size = " << st.largest_block() << ";\n";
    os << "  // The largest system a Newton iteration solves (torn blocks: their tear "
          "variables).\n";
    os << "  static constexpr int max_newton_size = " << st.largest_newton() << ";\n";
    emit_newton_coordinates(os, st);
    const SolverPlan plan = plan_block_solver(model, symbols, st, compiled.block_program(),
                                              options.max_function_ops, options.roll_min);
    BlockSolverPrinter blocks(model, symbols, plan);
    // Spatial files: every solve checks its branch, and the first solve's continuation runs
    // on the block-linear kernels and tables.
    const bool spatial_first = m.spatial && linear_blocks_supported(st);
    if (m.spatial) blocks.check_branches();
    os << "  // Values in the optional sin/cos cache of solve_position and solve_step (3 per\n"
       << "  // coordinate whose sin or cos the model uses).\n"
       << "  static constexpr int trig_cache_size = " << blocks.trig_cache_size() << ";\n\n";
    // Linear solves with Phi_q after a position solve (the block_linear kernel): parameter
    // sensitivities and kinetostatics append their functions after the block functions.
    std::ostringstream linear;
    if (linear_blocks_supported(st)) {
      emit_sensitivity(linear, compiled, options);
      // The force functions take qdd, which only a header with the accelerations gives.
      if (acceleration)
        emit_forces(linear, compiled, options, plan.program.trig_slot);
    }
    const std::string linear_code = linear.str();
    // With forces solve_step keeps its factors for solve_forces.
    if (linear_code.find("_block_transposed_reusing<") != std::string::npos)
      blocks.keep_step_factors();
    // The block functions first, so that only the kernels they call are emitted (before them).
    std::ostringstream code;
    if (linear_code.find("_block_transposed_reusing<") != std::string::npos)
      blocks.emit_step_factors(code);
    blocks.emit_position(code);
    if (velocity) {
      code << "\n";
      blocks.emit_motion(code, true, false);
    }
    if (acceleration) {
      code << "\n";
      blocks.emit_motion(code, false, true);
      code << "\n";
      blocks.emit_motion(code, true, true);
      code << "\n";
      blocks.emit_step(code);
    }
    blocks.emit_rolls(code, velocity, acceleration);
    // The tables only where a function reads them (folded headers say has_sensitivity = false).
    if (spatial_first || linear_code.find("_block_forward<") != std::string::npos ||
        linear_code.find("_block_transposed_reusing<") != std::string::npos)
      emit_structure_tables(os, m.name, st, compiled.programs());
    code << linear_code;
    emit_kernels(os, code.str(), spatial_first);
    if (code.str().find("_trig(") != std::string::npos)
      os << "  // The sin/cos cache, constructed empty: `TrigCache<double> cache;` then "
            "cache.data().\n"
         << "  template <class T>\n"
         << "  using TrigCache = BasicTrigCache<T, trig_cache_size>;\n\n";
    os << code.str();
  }
}

}  // namespace

std::string emit_header(const CompiledModel& compiled, const EmitOptions& options) {
  const Mechanism& m = compiled.mechanism();
  const SymbolTable& symbols = compiled.symbols();
  const SymbolicModel& model = compiled.symbolic();
  const ModelPrograms& programs = compiled.programs();
  check_header_names(m);  // a name the header cannot carry is refused here, with the reason
  if (const auto why = namespace_conflict(options.name_space); !why.empty())
    throw UsageError("--namespace: " + why);
  static const Structure kNone;  // no block solver: the section-4 functions alone
  const Structure& st =
      options.block_solver && programs.nq == programs.nc ? compiled.structure() : kNone;
  std::ostringstream os;
  emit_banner(os, m, options, compiled.build_options().fold_params);
  emit_model_tables(os, m, symbols, model, programs);
  emit_params(os, m, symbols, model, compiled.build_options().fold_params);
  // The expression kernels (motion laws, pieces, tables) are inserted here once it is known
  // which ones the functions call.
  const auto expression_kernels_at = static_cast<std::size_t>(os.tellp());
  emit_constraint_functions(os, symbols, model, programs, options);
  if (programs.num_outputs > 0) emit_outputs(os, m, symbols, programs, options.max_function_ops);
  emit_output_flags(os, options);
  if (m.spatial) emit_spatial(os, compiled, options);
  emit_block_solver(os, compiled, st, options);
  os << "};\n\n}  // namespace " << options.name_space << "\n";
  return with_input_members(with_expression_kernels(os.str(), expression_kernels_at), m);
}

}  // namespace kinegen::codegen

// The header's forward dynamics: dynamics(), the minimal coordinates' accelerations by the
// block program and the dynamics kernel, as `kinegen simulate` computes them
// (analysis/dynamics.cpp). Printed after the force functions it calls.
#include <algorithm>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "kinegen/codegen/symbolic/forces.hpp"
#include "kinegen/codegen/symbolic/tangent.hpp"
#include "kinegen/kernels/linearize.hpp"
#include "printer.hpp"
#include "sections.hpp"

namespace kinegen::codegen::emit_detail {

namespace {

// Each free item's row of Phi: the rows of the joints and of the drivers before it.
std::vector<int> free_rows(const Mechanism& m) {
  std::vector<int> rows;
  const int nj = static_cast<int>(m.joints.size());
  for (int d : m.free_drivers()) {
    int row = 0;
    for (int c = 0; c < nj + d; ++c) row += m.constraints()[c]->equation_count();
    rows.push_back(row);
  }
  return rows;
}

void emit_dynamics_tables(std::ostringstream& os, const Mechanism& m,
                          const std::vector<int>& mass_at, int geometry_size) {
  std::vector<std::string> names, rows, distance, at;
  for (int d : m.free_drivers()) {
    names.push_back("\"" + m.drivers[d].name + "\"");
    distance.push_back(is_distance(m.drivers[d]) ? "true" : "false");
  }
  for (int r : free_rows(m)) rows.push_back(idx(r));
  for (int a : mass_at) at.push_back(idx(a));
  os << "\n  // ---- Forward dynamics in minimal coordinates: the "
        "free\n"
     << "  // items are the coordinates z; q(z, t) by the block solver with z as drivers' values,\n"
     << "  // qd = B zd + b and qdd = B zdd + c with B = dq/dz, then (B^T M B) zdd = B^T (Q^A - M "
        "c)\n"
     << "  // by the dynamics kernel: what `kinegen simulate` computes.\n"
     << "  static constexpr bool has_dynamics = true;\n"
     << "  static constexpr int nf = " << names.size() << ";  // free coordinates\n"
     << "  static constexpr int num_bodies = " << m.bodies.size() << ";\n"
     << "  static constexpr std::array<const char*, nf> free_names = {" << join(names) << "};\n"
     << "  // Each free item's row of Phi: quantity - z, or for a distance |d|^2 - z^2.\n"
     << "  static constexpr std::array<int, nf> free_rows = {" << join(rows) << "};\n"
     << "  static constexpr std::array<bool, nf> free_distance = {" << join(distance) << "};\n"
     << "  // Where each body's m, J and A com start in _force_geometry's output (-1: no mass).\n"
     << "  static constexpr std::array<int, num_bodies> _mass_at = {" << join(at) << "};\n\n"
     << "  // dynamics()' state and work space, caller-owned (no heap). q, qd and qdd are the "
        "last\n"
     << "  // call's (q: the next position solve's start, the file's q0 at first); state holds\n"
     << "  // z, zd and zdd, block_signs each Newton block's determinant sign (a change: status "
        "6).\n"
     << "  template <class T>\n"
     << "  struct DynamicsWork {\n"
     << "    T q[nq], qd[nq], qdd[nq], state[3 * nf];\n"
     << "    signed char block_signs[num_blocks];\n"
     << "    T jac[jac_nnz], e[nq * nf], b[nq * nf], mb[nq * nf], g[nq], f[nq], mz[nf * nf];\n"
     << "    T factors[block_factor_begin[num_blocks]];  // Phi_q's blocks at q\n"
     << "    // The position solves' sin/cos cache, kept from call to call as the command line\n"
     << "    // keeps it (so that the solves are the same bits) and as kinegen::Solver does.\n"
     << "    T trig[trig_cache_size > 0 ? trig_cache_size : 1];\n"
     << "    int pivots[nq];\n"
     << "    T geometry[" << geometry_size << "], mass[num_bodies], inertia[num_bodies], "
     << "ax[num_bodies], ay[num_bodies];\n"
     << "    // The last dynamics()' arguments, q and report where it succeeded (solved), whose\n"
     << "    // B and factors dynamics_jacobians reuses; a later failed dynamics() clears it, and\n"
     << "    // so does a new q written by the caller (compared).\n"
     << "    bool solved = false;\n"
     << "    T solved_t = T(0), solved_q[nq];\n"
     << "    Params solved_p;\n"
     << "    BasicBlockOptions<_real<T>> solved_o;\n"
     << "    BlockReport<_real<T>> solved_r;\n"
     << "    // The z of the last successful dynamics() (assembled), which q continues: a call\n"
     << "    // whose z is further away, or the first, reaches z by continuation "
        "(_continue_free).\n"
     << "    bool assembled = false;\n"
     << "    T assembled_z[nf];\n"
     << "    DynamicsWork() noexcept { reset(); }\n"
     << "    // Back to the file's q0, no recorded branch, an empty cache (a new start).\n"
     << "    void reset() noexcept {\n"
     << "      solved = false;\n"
     << "      assembled = false;\n"
     << "      for (T& v : assembled_z) v = T(0);\n"
     << "      for (int k = 0; k < nq; ++k) q[k] = T(q0[k]);\n"
     << "      for (int k = 0; k < num_blocks; ++k) block_signs[k] = 0;\n"
     << "      for (T& v : trig) v = T(std::numeric_limits<_real<T>>::quiet_NaN());  // empty\n"
     << "    }\n"
     << "  };\n\n";
}

void emit_dynamics_function(std::ostringstream& os) {
  os << R"(  // zdd[nf] at (z, zd, t) and, in w, q, qd, qdd. The status is solve_step's, or 2 where
  // B^T M B's LDL^T pivot ratio is at most options.singular_pivot_ratio (a free coordinate
  // that moves no mass), 3 where a value is not finite; block -1 for the reduction.
  template <class T, class U>
  static BlockReport<_real<T>> dynamics(const T* z, const T* zd, T t, const Params& p, T* zdd,
      const BasicBlockOptions<U>& options, DynamicsWork<T>& w) noexcept {
    using R = _real<T>;
    const BasicBlockOptions<R> o = _options_as<R>(options);
    Params pz = p;
    w.solved = false;
    for (int k = 0; k < nf; ++k) {
      w.state[k] = z[k];
      w.state[nf + k] = zd[k];
      w.state[2 * nf + k] = T(0);  // qdd = c first: the accelerations at zdd = 0
    }
    pz._free = w.state;
    if (_far_from_assembly(z, w)) {
      const BlockReport<R> rc = _continue_free(z, t, pz, o, w);
      if (rc.status != 0) return rc;
    }
    BlockReport<R> r = solve_step(w.q, t, pz, w.qd, w.qdd, o, w.trig, w.block_signs);
    if (r.status != 0) return r;
    // B: Phi_q B = -Phi_z, the free rows' unit vectors (2 z for |d|^2 - z^2), each block
    // factored once (the factors kept for dynamics_jacobians' solves at this q).
    phi_q(w.q, t, pz, w.jac);
    for (int i = 0; i < nq * nf; ++i) w.e[i] = T(0);
    for (int k = 0; k < nf; ++k)
      w.e[k * nq + free_rows[k]] = free_distance[k] ? T(2) * z[k] : T(1);
    const BlockReport<R> rb = _block_factor_all<_model>(w.jac, w.factors, w.pivots, o);
    if (rb.status != 0) return _fail(r, rb.status, rb.block);
    if (rb.rcond < r.rcond) r.rcond = rb.rcond;
    if (!_block_forward_factored<_model>(w.jac, w.factors, w.pivots, w.e, w.b, nf))
      return _fail(r, _kStatusNonFinite, -1);
    // Each body's mass data; g = Q^A - (M qdd + h) at qdd = c, generalized_force's numbers
    // (the same products; the geometry computed once for both).
    _force_geometry(w.q, t, pz, w.geometry);
    for (int i = 0; i < num_bodies; ++i) {
      const int a = _mass_at[i];
      w.mass[i] = a < 0 ? T(0) : w.geometry[a];
      w.inertia[i] = a < 0 ? T(0) : w.geometry[a + 1];
      w.ax[i] = a < 0 ? T(0) : w.geometry[a + 2];
      w.ay[i] = a < 0 ? T(0) : w.geometry[a + 3];
    }
    applied_force(w.q, w.qd, t, pz, w.g);
    _inertia_forces(num_bodies, nq, w.mass, w.inertia, w.ax, w.ay, w.qd, w.qdd, w.f);
    for (int k = 0; k < nq; ++k) w.g[k] -= w.f[k];
    for (int k = 0; k < nf; ++k)
      _mass_times(num_bodies, nq, w.mass, w.inertia, w.ax, w.ay, w.b + k * nq, w.mb + k * nq);
    const R ratio = _reduced_accelerations(nq, nf, w.b, w.mb, w.g, w.mz, zdd, w.qdd);
    if (!(ratio == ratio)) return _fail(r, _kStatusNonFinite, -1);
    if (!(ratio > o.singular_pivot_ratio)) return _fail(r, _kStatusSingular, -1);
    if (!_all_finite<nf>(zdd) || !_all_finite<nq * nf>(w.b)) return _fail(r, _kStatusNonFinite, -1);
    for (int k = 0; k < nf; ++k) w.state[2 * nf + k] = zdd[k];
    w.solved = true;
    w.solved_t = t;
    for (int k = 0; k < nq; ++k) w.solved_q[k] = w.q[k];
    w.solved_p = p;
    w.solved_o = o;
    w.solved_r = r;
    w.assembled = true;
    for (int k = 0; k < nf; ++k) w.assembled_z[k] = z[k];
    return r;
  }

  // First solves and branches (docs/embedding.md): a fresh work space's position, or one whose
  // z is more than a continuation step from the last solved z, is reached by continuation from
  // w.q: each free item moves from its value at w.q (the file's q0 pose at first) to z in
  // steps of at most 0.25 rad (an angle) or 0.1 length_scale (a length, a distance), each a
  // position solve from the last; the first step records the blocks' determinant signs (a
  // fresh work space) and every later solve holds them (status 6).
  template <class T>
  static _real<T> _continuation_need(const T& from, const T& to, int k) noexcept {
    using R = _real<T>;
    const bool angle = !free_distance[k] && coordinate_kinds[_free_column(k)] == 1;
    return _mag(to - from) / (angle ? R(0.25) : R(0.1 * length_scale));
  }
  template <class T>
  static bool _far_from_assembly(const T* z, const DynamicsWork<T>& w) noexcept {
    if (!w.assembled) return true;
    for (int k = 0; k < nf; ++k)
      if (!(_continuation_need(w.assembled_z[k], z[k], k) <= 1)) return true;
    return false;
  }
  template <class T, class R>
  static BlockReport<R> _continue_free(const T* z, T t, Params& pz, const BasicBlockOptions<R>& o,
                                       DynamicsWork<T>& w) noexcept {
    using std::sqrt;
    BlockReport<R> r;
    // The free items' values at w.q: each free row at z = 0 is the quantity (a distance's:
    // its square).
    T from[nf], out[nc];
    for (int k = 0; k < nf; ++k) w.state[k] = T(0);
    phi(w.q, t, pz, out);
    R need = 0;
    for (int k = 0; k < nf; ++k) {
      from[k] = free_distance[k] ? T(sqrt(out[free_rows[k]])) : out[free_rows[k]];
      const R n = _continuation_need(from[k], z[k], k);
      if (!(n <= need)) need = n;
    }
    if (!(need == need)) return _fail(r, _kStatusNonFinite, -1);
    if (need > R(_kMaxContinuationSteps)) return _fail(r, _kStatusTooFar, -1);
    const int steps = need > 1 ? static_cast<int>(std::ceil(need)) : 1;
    for (int i = 1; i < steps && r.status == 0; ++i) {
      for (int k = 0; k < nf; ++k) w.state[k] = from[k] + (z[k] - from[k]) * T(i) / T(steps);
      r = solve_position(w.q, t, pz, o, w.trig, w.block_signs);
    }
    for (int k = 0; k < nf; ++k) w.state[k] = z[k];
    return r;
  }

  // The same from the file's q0, with no state kept: the first call of a motion, or a test.
  template <class T, class U>
  static BlockReport<_real<T>> dynamics(const T* z, const T* zd, T t, const Params& p, T* zdd,
      const BasicBlockOptions<U>& options) noexcept {
    DynamicsWork<T> w;
    return dynamics(z, zd, t, p, zdd, options, w);
  }
)";
}

// _solved_at: dynamics_jacobians' test for reusing the last dynamics().
void emit_solved_at(std::ostringstream& os) {
  os << R"(
  // Whether w holds a successful dynamics() with exactly these arguments (bit for bit) and its
  // own q.
  template <class T, class U>
  static bool _solved_at(const T* z, const T* zd, T t, const Params& p,
                         const BasicBlockOptions<U>& options, const DynamicsWork<T>& w) noexcept {
    if (!w.solved || !_same_bits(t, w.solved_t) || !_same_params(p, w.solved_p) ||
        !_same_options(_options_as<_real<T>>(options), w.solved_o))
      return false;
    for (int k = 0; k < nf; ++k)
      if (!_same_bits(z[k], w.state[k]) || !_same_bits(zd[k], w.state[nf + k])) return false;
    for (int k = 0; k < nq; ++k)
      if (!_same_bits(w.q[k], w.solved_q[k])) return false;
    return true;
  }
)";
}

// ---- The exact Jacobians: the tangent's derivatives as one program, the compile stage's
// TangentProgram that the command line's Linearizer (analysis/tangent.cpp) evaluates too, and
// the linearize kernel's _dynamics_tangent on the header's block solves.

std::string int_array(const std::string& name, const std::vector<int>& v) {
  std::vector<std::string> s;
  for (int x : v) s.push_back(idx(x));
  return "  static constexpr std::array<int, " + idx(static_cast<int>(v.size())) + "> " + name +
         " = {" + join(s) + "};\n";
}

void emit_tangent_tables(std::ostringstream& os, const TangentModel& t,
                         const std::vector<int>& begin) {
  const HessianExpr& h = t.phi_qq;
  os << int_array("_tangent_begin", begin) << int_array("_phi_qq_row", h.row)
     << int_array("_phi_qq_j", h.j) << int_array("_phi_qq_k", h.k);
  const std::pair<const char*, const SparseExpr*> pieces[] = {
      {"_nu_q", &t.nu_q},           {"_gamma_q", &t.gamma_q},
      {"_gamma_qd", &t.gamma_qd},   {"_phi_w", &t.phi_w},
      {"_nu_w", &t.nu_w},           {"_gamma_w", &t.gamma_w},
      {"_applied_q", &t.applied_q}, {"_applied_qd", &t.applied_qd},
      {"_applied_w", &t.applied_w}};
  for (const auto& [name, piece] : pieces)
    os << int_array(std::string(name) + "_row", piece->row)
       << int_array(std::string(name) + "_col", piece->col);
}

// The directions: each free item's value and rate slot (3 per driver), then the inputs'.
std::vector<int> tangent_slots(const Mechanism& m) {
  std::vector<int> slots;
  for (int d : m.free_drivers()) slots.push_back(3 * d);
  for (int d : m.free_drivers()) slots.push_back(3 * d + 1);
  for (const RunInput& in : run_inputs(m)) slots.push_back(in.slot);
  return slots;
}

// The rest of dynamics_jacobians: the kernel on the block solves, the columns copied out.
void emit_jacobians_solve(std::ostringstream& os) {
  os << R"(    // Phi_q's entries and blocks' factors at q are dynamics()' (w.jac, w.factors). The
    // solves skip their blocks' finiteness checks: the kernel checks the Jacobians, which any
    // non-finite value of the solutions reaches.
    const int s = _dynamics_tangent<nq, nf, num_bodies>(
        tp, ndir, _tangent_slots.data(), out, work,
        [&](T* b, T* x, int m) {
          _block_forward_factored<_model, false>(w.jac, w.factors, w.pivots, b, x, m);
          return 0;
        },
        [&](T* b, T* y, int m) {
          _block_transposed_factored<_model, false>(w.jac, w.factors, w.pivots, b, y, m);
          return 0;
        });
    if (s != 0) return _fail(r, s, -1);
    for (int i = 0; i < nf * nf; ++i) {
      if (d_z) d_z[i] = out[i];
      if (d_zd) d_zd[i] = out[nf * nf + i];
    }
    if (d_u)
      for (int i = 0; i < nf * num_inputs; ++i) d_u[i] = out[2 * nf * nf + i];
    return r;
  }

  // The same with the work space on the stack.
  template <class T, class U>
  static BlockReport<_real<T>> dynamics_jacobians(const T* z, const T* zd, T t, const Params& p,
      T* zdd, _given<T>* d_z, _given<T>* d_zd, _given<T>* d_u,
      const BasicBlockOptions<U>& options, DynamicsWork<T>& w) noexcept {
    JacobianWork<T> j;
    return dynamics_jacobians(z, zd, t, p, zdd, d_z, d_zd, d_u, options, w, j);
  }
)";
}

// The work space's sizes, in T's: the tangent's values, the outputs and the kernel's.
struct JacobianSizes {
  int values, out, work;
};

JacobianSizes jacobian_sizes(int num_values, int ndir, int nq, int nf) {
  return {std::max(num_values, 1), nf * ndir,
          kernels::LinearizeKernel::_tangent_work_size(nq, nf, ndir)};
}

// JacobianWork: the work space and a sin/cos cache.
void emit_jacobian_work(std::ostringstream& os, const JacobianSizes& z, int ndir, int own_trig) {
  os << "  // dynamics_jacobians' work space, caller-owned (no heap); it uses the stack instead\n"
     << "  // where the arrays take at most KINEGEN_STACK_WORK_BYTES.\n"
     << "  template <class T>\n"
     << "  struct JacobianWork {\n"
     << "    T values[" << z.values << "];  // _tangent_values\n"
     << "    T out[nf * " << ndir << "];\n"
     << "    T work[" << z.work << "];  // _tangent_work_size(nq, nf, " << ndir << ")\n";
  if (own_trig > 0)
    os << "    // A sin/cos cache of the angles dynamics() does not cache, kept from call to\n"
       << "    // call: a call near the last costs a rotation, not a sin and a cos.\n"
       << "    BasicTrigCache<T, " << 3 * own_trig << "> trig;\n"
       << "    // Empties the cache (a new start: the same numbers as a fresh JacobianWork).\n"
       << "    void reset() noexcept { trig.clear(); }\n";
  else
    os << "    void reset() noexcept {}  // nothing is kept from call to call\n";
  os << "  };\n\n";
}

// dynamics_jacobians' arrays: on the stack when they take at most KINEGEN_STACK_WORK_BYTES,
// where the compiler sees that nothing else writes them and keeps values in registers rather
// than storing and reloading them (the pendulum 28 -> 19 ns), else JacobianWork's.
std::string jacobian_arrays(const JacobianSizes& z) {
  // Three arrays, not one: the compiler then knows that writing one leaves the others.
  std::ostringstream os;
  os << "    // The work space: on the stack where it is small (the compiler then sees that "
        "nothing\n"
     << "    // else writes it), else JacobianWork's.\n"
     << "    constexpr bool on_stack = sizeof(T) * (" << z.values << " + " << z.out << " + "
     << z.work << ") <= KINEGEN_STACK_WORK_BYTES;\n"
     << "    T stack_values[on_stack ? " << z.values << " : 1], stack_out[on_stack ? " << z.out
     << " : 1], stack_work[on_stack ? " << z.work << " : 1];\n"
     << "    T* const values = on_stack ? stack_values : j.values;\n"
     << "    T* const out = on_stack ? stack_out : j.out;\n"
     << "    T* const work = on_stack ? stack_work : j.work;\n";
  return os.str();
}

void emit_jacobians_function(std::ostringstream& os, int num_values, int ndir, int nq, int nf,
                             int own_trig) {
  const JacobianSizes sizes = jacobian_sizes(num_values, ndir, nq, nf);
  emit_jacobian_work(os, sizes, ndir, own_trig);
  os << R"(  // dynamics() and the exact d(zdd)/dz (d_z), d(zdd)/dzd (d_zd) and d(zdd)/du (d_u)
  // there, each column-major (d_z[j * nf + i] = d zdd_i / d z_j; d_u: nf x num_inputs), any
  // of them nullptr when not wanted: A = [0 I; d_z d_zd] and B = [0; d_u] of x' = f(x, u),
  // x = (z, zd), as `kinegen linearize` gives them. The linearize kernel on the block solves
  // (on dynamics()' factors). Status as dynamics()', or the tangent's (2, 3). Where the last
  // call with w was a successful dynamics() with the same arguments (as in an integrator's or
  // a controller's step, which evaluate f there first), its solution is used, not solved
  // again: the Jacobians then cost the tangent alone.
  template <class T, class U>
  KINEGEN_NO_SLP static BlockReport<_real<T>> dynamics_jacobians(const T* z, const T* zd, T t,
      const Params& p, T* zdd, _given<T>* d_z, _given<T>* d_zd, _given<T>* d_u,
      const BasicBlockOptions<U>& options, DynamicsWork<T>& w, JacobianWork<T>& j) noexcept {
    using R = _real<T>;
    BlockReport<R> r;
    if (_solved_at(z, zd, t, p, options, w)) {
      r = w.solved_r;
      for (int k = 0; k < nf; ++k) zdd[k] = w.state[2 * nf + k];
    } else {
      r = dynamics(z, zd, t, p, zdd, options, w);
      if (r.status != 0) return r;
    }
    if (!d_z && !d_zd && !d_u) return r;
    Params pz = p;
    pz._free = w.state;  // z, zd and now zdd, which gamma of a distance item reads
)" << jacobian_arrays(sizes)
     << "    _tangent_values(w.q, w.qd, t, pz, values, w.trig, "
     << (own_trig > 0 ? "j.trig.data()" : "static_cast<T*>(nullptr)") << ");\n"
     << R"(    // Every direction, whichever are asked for: constant directions fold into the kernel's
    // loops (a free coordinate's value or rate is known to it: its dq or dqd is B's column).
    constexpr int ndir = 2 * nf + num_inputs;
    const auto at = [&](int piece) { return values + _tangent_begin[piece]; };
    _TangentPoint<T> tp;
    tp.nq = nq;
    tp.nf = nf;
    tp.nb = num_bodies;
    tp.q = w.q;
    tp.qd = w.qd;
    tp.qdd = w.qdd;
    tp.b = w.b;
    tp.mass = w.mass;
    tp.inertia = w.inertia;
    tp.ax = w.ax;
    tp.ay = w.ay;
    tp.applied = at(7);
    tp.mb = w.mb;
    tp.mz = w.mz;  // factored by dynamics()
    tp.known = _tangent_known.data();
    tp.n_r_rows = static_cast<int>(_tangent_r_rows.size());
    tp.r_rows = _tangent_r_rows.data();
    tp.phi_qq = {static_cast<int>(_phi_qq_row.size()), _phi_qq_row.data(), _phi_qq_j.data(),
                 _phi_qq_k.data(), at(0)};
    const auto sparse = [&](const auto& row, const auto& col, int piece) {
      return _Sparse<T>{static_cast<int>(row.size()), row.data(), col.data(), at(piece)};
    };
    tp.nu_q = sparse(_nu_q_row, _nu_q_col, 1);
    tp.gamma_q = sparse(_gamma_q_row, _gamma_q_col, 2);
    tp.gamma_qd = sparse(_gamma_qd_row, _gamma_qd_col, 3);
    tp.phi_w = sparse(_phi_w_row, _phi_w_col, 4);
    tp.nu_w = sparse(_nu_w_row, _nu_w_col, 5);
    tp.gamma_w = sparse(_gamma_w_row, _gamma_w_col, 6);
    tp.applied_q = sparse(_applied_q_row, _applied_q_col, 8);
    tp.applied_qd = sparse(_applied_qd_row, _applied_qd_col, 9);
    tp.applied_w = sparse(_applied_w_row, _applied_w_col, 10);
)";
  emit_jacobians_solve(os);
}

// _tangent_values(q, qd, t, p, out, trig, own). sin and cos of the coordinates come from
// caches (_trig): a coordinate the block solver caches from DynamicsWork's (trig), anchored
// where dynamics()' solves started (q itself unless an angle moved by more than _trig's
// limit, which then anchors the cache at q, as the next solve would); any other from
// JacobianWork's (own), anchored by the calls before. Near an anchor they cost a rotation,
// not a sin and a cos (to a rounding of them). A function split in parts evaluates them
// itself and ignores both. Returns the number of `own` slots.
int emit_tangent_values(std::ostringstream& os, const Program& program, int num_values,
                        const DynamicsSource& d) {
  const int max_ops = d.options.max_function_ops;
  const std::string size = idx(std::max(num_values, 1));
  if (split_function(program, max_ops)) {
    emit_function(os, "_tangent_values", size.c_str(), program, d.symbols, true, max_ops);
    os << "  template <class T>\n"
       << "  static void _tangent_values(const T* q, const T* qd, T t, const Params& p, T* out,\n"
       << "                              T*, T*) noexcept {\n"
       << "    _tangent_values(q, qd, t, p, out);\n"
       << "  }\n";
    return 0;
  }
  FunctionPrinter pr(program, d.symbols);
  std::ostringstream trig;
  int own = 0;  // slots in `own`
  std::set<int> declared;
  for (std::size_t id = 0; id < program.nodes.size(); ++id) {
    const Node& n = program.nodes[id];
    if (n.kind != OpKind::kSin && n.kind != OpKind::kCos) continue;
    const Node& a = program.nodes[n.args[0]];
    if (a.kind != OpKind::kInput || a.input.kind != InputKind::kQ) continue;
    const int c = a.input.index;
    const bool cached = c < static_cast<int>(d.trig_slot.size()) && d.trig_slot[c] >= 0;
    if (declared.insert(c).second) {
      const int slot = cached ? d.trig_slot[c] : own++;
      trig << "    T _sin" << c << ", _cos" << c << ";\n    _trig(_sin" << c << ", _cos" << c
           << ", q[" << c << "], " << (cached ? "trig" : "own") << ", " << slot << ");\n";
    }
    pr.bind(static_cast<int>(id), (n.kind == OpKind::kSin ? "_sin" : "_cos") + idx(c));
  }
  os << "  template <class T>\n"
     << "  static void _tangent_values([[maybe_unused]] const T* q, [[maybe_unused]] const T* qd,\n"
     << "      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* out,\n"
     << "      [[maybe_unused]] T* trig, [[maybe_unused]] T* own) noexcept {\n"
     << "    // out[" << size << "]; " << program.operation_count() << " operations\n";
  if (const std::string used = std_functions(program); !used.empty())
    os << "    using " << used << ";\n";
  if (!trig.str().empty())
    os << "    // sin and cos from the caches: DynamicsWork's (trig), JacobianWork's (own)\n"
       << trig.str();
  os << pr.body("    ") << "  }\n";
  return own;
}

void emit_jacobians(std::ostringstream& os, const DynamicsSource& d) {
  const std::shared_ptr<const TangentProgram> tangent = d.compiled.tangent_program(d.forces);
  const TangentModel& t = tangent->tangent;
  const std::vector<int>& begin = tangent->begin;
  Program program = tangent->program;
  const int num_values = static_cast<int>(program.outputs.size());
  if (program.outputs.empty()) program.outputs.push_back(Program::kZero);  // out[1]: reads `out`
  const std::vector<int> slots = tangent_slots(d.m);
  std::vector<std::string> names;
  for (const RunInput& in : run_inputs(d.m)) names.push_back("\"" + in.name + "\"");
  const int nf = d.m.num_free(), ndir = static_cast<int>(slots.size());
  os << "\n  // ---- The exact Jacobians of zdd(z, zd, u), for linear-quadratic and\n"
     << "  // model-predictive control: the run-time inputs u are the loads' (Params members).\n"
     << "  static constexpr bool has_dynamics_jacobians = true;\n"
     << "  static constexpr int num_inputs = " << names.size() << ";\n"
     << "  static constexpr std::array<const char*, num_inputs> input_names = {" << join(names)
     << "};\n\n private:\n"
     << "  // The tangent's derivatives (symbolic/tangent.hpp): Phi_qq, nu_q, gamma_q, gamma_qd,\n"
     << "  // Phi_w, nu_w, gamma_w, Q^A, Q^A_q, Q^A_qd and Q^A_w (w: the input slots, 3 per "
        "driver\n"
     << "  // then the loads' inputs), each starting at _tangent_begin[piece], and their places.\n";
  emit_tangent_tables(os, t, begin);
  os << int_array("_tangent_slots", slots);
  // The kernel's: z_k and zd_k have B's column as dq and dqd; a slot that Phi, nu and gamma
  // do not read (a load's input) moves neither q nor qd (_kStill).
  const auto reads = [&](const SparseExpr& e, int slot) {
    return std::find(e.col.begin(), e.col.end(), slot) != e.col.end();
  };
  std::vector<int> known;
  for (int i = 0; i < ndir; ++i) {
    const bool still =
        !reads(t.phi_w, slots[i]) && !reads(t.nu_w, slots[i]) && !reads(t.gamma_w, slots[i]);
    known.push_back(i < 2 * nf ? i : still ? kernels::LinearizeKernel::_kStill : -1);
  }
  os << int_array("_tangent_known", known);
  // The rows the acceleration residual r_a can be non-zero on (the kernel's r_rows).
  std::set<int> r_rows(t.phi_qq.row.begin(), t.phi_qq.row.end());
  for (const SparseExpr* e : {&t.gamma_q, &t.gamma_qd, &t.gamma_w})
    r_rows.insert(e->row.begin(), e->row.end());
  os << int_array("_tangent_r_rows", std::vector<int>(r_rows.begin(), r_rows.end()));

  const int own_trig = emit_tangent_values(os, program, num_values, d);
  os << "\n public:\n";
  emit_jacobians_function(os, num_values, ndir, static_cast<int>(d.model.coordinate_kinds.size()),
                          nf, own_trig);
}

// step_implicit and what both steps share.
void emit_implicit_step(std::ostringstream& os) {
  os << R"(
  template <class T, class U>
  static BlockReport<_real<T>> step_implicit(T* z, T* zd, T& t, T h, const Params& p,
      const BasicBlockOptions<U>& options, DynamicsWork<T>& w, JacobianWork<T>& j,
      int newton_iterations = 10,
      _real<T> newton_tolerance = BasicBlockOptions<_real<T>>().tolerance) noexcept {
    using R = _real<T>;
    T x[2 * nf];
    R scale[2 * nf];
    for (int k = 0; k < nf; ++k) scale[k] = scale[nf + k] = R(free_scale(k));
    BlockReport<R> r;
    const auto f = [&](T at, const T* y, T* yd) {
      for (int k = 0; k < nf; ++k) yd[k] = y[nf + k];
      r = dynamics(y, y + nf, at, p, yd + nf, options, w);
      return r.status;
    };
    const auto jacobian = [&](T at, const T* y, const T*, T* a) {
      T zdd[nf], dz[nf * nf], dzd[nf * nf];
      r = dynamics_jacobians(y, y + nf, at, p, zdd, dz, dzd, nullptr, options, w, j);
      _state_jacobian<nf>(dz, dzd, a);
      return r.status;
    };
    const int status = _sdirk2_step<2 * nf>(t, h, _state_in(z, zd, x), scale, f, jacobian,
                                            newton_iterations, newton_tolerance);
    return _step_with(z, zd, t, h, x, r, status);
  }

 private:
  template <class T>
  static T* _state_in(const T* z, const T* zd, T* x) noexcept {
    for (int k = 0; k < nf; ++k) {
      x[k] = z[k];
      x[nf + k] = zd[k];
    }
    return x;
  }
  // The step's end: x back into z and zd and t + h, or the failure (a dynamics() report, or
  // the kernel's status: 1 Newton, 2 singular, 3 not finite).
  template <class T, class R>
  static BlockReport<R> _step_with(T* z, T* zd, T& t, T h, const T* x, BlockReport<R> r,
                                   int status) noexcept {
    if (status != 0) return r.status != 0 ? r : _fail(r, status, -1);
    for (int k = 0; k < nf; ++k) {
      z[k] = x[k];
      zd[k] = x[nf + k];
    }
    t += h;
    return r;
  }
  // The coordinate a free item's row reads first, for its kind (angle or length).
  static constexpr int _free_column(int k) noexcept {
    for (int e = 0; e < jac_nnz; ++e)
      if (jac_rows[e] == free_rows[k]) return jac_cols[e];
    return 0;
  }

 public:
  // The size of free coordinate k (and of its rate, per second) in the integrators' error
  // tests and Newton steps: 1 for an angle, length_scale for a length or a distance.
  static constexpr double free_scale(int k) noexcept {
    return free_distance[k] || coordinate_kinds[_free_column(k)] != 1 ? length_scale : 1.0;
  }
)";
}

// The integrators (the integrate kernel) on dynamics(): a fixed step of x = (z, zd).
void emit_steps(std::ostringstream& os) {
  os << R"(
  // ---- Fixed-step integrators for a control loop (kinegen::Simulator wraps them
  // with more care): z, zd and t advance by h in place, or stay as they were when a dynamics()
  // fails (its report). step_rk4: classical Runge-Kutta (4 dynamics() a step, explicit);
  // step_implicit: the L-stable SDIRK2 for stiff springs, Newton on the exact Jacobians, each
  // stage until its update (per scale: angles in radians, lengths over length_scale) is at
  // most newton_tolerance (the scalar's position tolerance by default; status 1 after
  // newton_iterations).
  template <class T, class U>
  static BlockReport<_real<T>> step_rk4(T* z, T* zd, T& t, T h, const Params& p,
      const BasicBlockOptions<U>& options, DynamicsWork<T>& w) noexcept {
    T x[2 * nf];
    BlockReport<_real<T>> r;
    const auto f = [&](T at, const T* y, T* yd) {
      for (int k = 0; k < nf; ++k) yd[k] = y[nf + k];
      r = dynamics(y, y + nf, at, p, yd + nf, options, w);
      return r.status;
    };
    const int status = _rk4_step<2 * nf>(t, h, _state_in(z, zd, x), f);
    return _step_with(z, zd, t, h, x, r, status);
  }
)";
  emit_implicit_step(os);
}

}  // namespace

void emit_dynamics(std::ostringstream& os, const DynamicsSource& d) {
  emit_dynamics_tables(os, d.m, d.mass_at, d.geometry_size);
  emit_dynamics_function(os);
  emit_solved_at(os);
  emit_jacobians(os, d);
  emit_steps(os);
}

}  // namespace kinegen::codegen::emit_detail

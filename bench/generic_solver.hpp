// A plain generic kinematic solver, the way DADS-style programs work: the mechanism is data
// (bodies, joint records with numbers, drivers f(t) = value + rate * t), and Phi, Phi_q, nu and
// gamma are assembled at run time by loops over the joint records, with the analytic formulas
// of Haug's planar joint library (looked up by the format's type name: no list of the
// generator's types here). No code generation, no symbolic algebra; dense LU (Eigen).
//
// It plugs into kinegen::BasicSolver as a System (dynamic sizes), so a comparison against the
// generated code runs the very same Newton iteration and LU: only the evaluation differs.
// Depends on Eigen and kinegen/solver.hpp only, so other benchmarks can reuse it.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <kinegen/solver.hpp>
#include <string>
#include <vector>

namespace kinegen::generic {

inline constexpr int kGround = -1;

struct JointFormulas;

// One joint or driver as numbers. `value` is the constant of a joint (value, length, angle);
// a driver uses f(t) = value + rate * t in its place.
struct JointRecord {
  const JointFormulas* formulas = nullptr;  // its type in the joint library
  int i = kGround, j = kGround;  // body indices (absolute_*: the body is i)
  Eigen::Vector2d si = Eigen::Vector2d::Zero(), sj = Eigen::Vector2d::Zero();
  Eigen::Vector2d vi = Eigen::Vector2d::UnitX();
  double value = 0, rate = 0;
  bool is_driver = false;

  int equation_count() const;
};

// A body's position, rotation, its derivative dA/dphi, and velocities (ground: all zero).
struct Frame {
  Eigen::Vector2d r = Eigen::Vector2d::Zero(), v = Eigen::Vector2d::Zero();
  double phi = 0, w = 0;
  Eigen::Matrix2d A = Eigen::Matrix2d::Identity(), B = Eigen::Matrix2d::Zero();

  static Frame of(const double* q, const double* qd, int body) {
    Frame f;
    f.B << 0, -1, 1, 0;
    if (body == kGround) return f;
    f.r = Eigen::Vector2d(q[3 * body], q[3 * body + 1]);
    f.phi = q[3 * body + 2];
    const double c = std::cos(f.phi), s = std::sin(f.phi);
    f.A << c, -s, s, c;
    f.B << -s, -c, c, -s;
    if (qd != nullptr) {
      f.v = Eigen::Vector2d(qd[3 * body], qd[3 * body + 1]);
      f.w = qd[3 * body + 2];
    }
    return f;
  }
};

// One joint type of the library, in closed form (Haug's formulas). The Jacobian of a joint's
// rows goes to jac[row][0..6): the columns x, y, phi of body i, then those of body j.
struct JointFormulas {
  const char* type;  // the mechanism format's name for it
  int rows;
  void (*phi)(const JointRecord& jr, const Frame& fi, const Frame& fj, double f, double* out);
  void (*jacobian)(const JointRecord& jr, const Frame& fi, const Frame& fj, double (*jac)[6]);
  void (*gamma)(const JointRecord& jr, const Frame& fi, const Frame& fj, double* out);
  // -Phi_t of the driven (last) row for a driver f(t) = value + rate t.
  double (*driven_rate)(const JointRecord& jr, double f);
};

inline int JointRecord::equation_count() const { return formulas->rows; }

namespace joints {

inline Eigen::Vector2d dij(const Frame& fi, const Frame& fj, const JointRecord& jr) {
  return fj.r + fj.A * jr.sj - fi.r - fi.A * jr.si;
}
// d_ij' along qd
inline Eigen::Vector2d ddij(const Frame& fi, const Frame& fj, const JointRecord& jr) {
  return fj.v + fj.B * jr.sj * fj.w - fi.v - fi.B * jr.si * fi.w;
}
// d'' along qd: -A_j sj w_j^2 + A_i si w_i^2, as aj - ai
inline Eigen::Vector2d centripetal(const Frame& f, const Eigen::Vector2d& s) {
  return f.A * s * (f.w * f.w);
}
inline double rate(const JointRecord& jr, double) { return jr.rate; }

// revolute: d_ij = 0
inline void revolute_phi(const JointRecord& jr, const Frame& fi, const Frame& fj, double,
                         double* out) {
  const Eigen::Vector2d d = dij(fi, fj, jr);
  out[0] = d.x();
  out[1] = d.y();
}
inline void revolute_jacobian(const JointRecord& jr, const Frame& fi, const Frame& fj,
                              double (*jac)[6]) {
  // d_ij = r_j + A_j sj - r_i - A_i si
  const Eigen::Vector2d bi = fi.B * jr.si, bj = fj.B * jr.sj;
  for (int c = 0; c < 2; ++c) {
    jac[c][c] = -1;
    jac[c][2] = -bi[c];
    jac[c][3 + c] = 1;
    jac[c][5] = bj[c];
  }
}
inline void revolute_gamma(const JointRecord& jr, const Frame& fi, const Frame& fj, double* out) {
  const Eigen::Vector2d g = centripetal(fj, jr.sj) - centripetal(fi, jr.si);
  out[0] = g.x();
  out[1] = g.y();
}

// revolute_translational: (B_i vi) . d_ij = 0; translational adds phi_j - phi_i - f = 0.
inline void slider_phi(const JointRecord& jr, const Frame& fi, const Frame& fj, double f,
                       double* out) {
  out[0] = (fi.B * jr.vi).dot(dij(fi, fj, jr));
  if (jr.formulas->rows == 2) out[1] = fj.phi - fi.phi - f;
}
inline void slider_jacobian(const JointRecord& jr, const Frame& fi, const Frame& fj,
                            double (*jac)[6]) {
  // n = B_i vi = (A_i vi)^perp, dn/dphi_i = -A_i vi
  const Eigen::Vector2d n = fi.B * jr.vi, d = dij(fi, fj, jr);
  jac[0][0] = -n.x();
  jac[0][1] = -n.y();
  jac[0][2] = -(fi.A * jr.vi).dot(d) - n.dot(fi.B * jr.si);
  jac[0][3] = n.x();
  jac[0][4] = n.y();
  jac[0][5] = n.dot(fj.B * jr.sj);
  if (jr.formulas->rows == 2) {
    jac[1][2] = -1;
    jac[1][5] = 1;
  }
}
inline void slider_gamma(const JointRecord& jr, const Frame& fi, const Frame& fj, double* out) {
  const Eigen::Vector2d n = fi.B * jr.vi, d = dij(fi, fj, jr), dd = ddij(fi, fj, jr);
  const Eigen::Vector2d ai = centripetal(fi, jr.si), aj = centripetal(fj, jr.sj);
  out[0] = fi.w * fi.w * n.dot(d) + 2 * fi.w * (fi.A * jr.vi).dot(dd) + n.dot(aj - ai);
  if (jr.formulas->rows == 2) out[1] = 0;
}

// distance: d . d - f^2 = 0
inline void distance_phi(const JointRecord& jr, const Frame& fi, const Frame& fj, double f,
                         double* out) {
  const Eigen::Vector2d d = dij(fi, fj, jr);
  out[0] = d.dot(d) - f * f;
}
inline void distance_jacobian(const JointRecord& jr, const Frame& fi, const Frame& fj,
                              double (*jac)[6]) {
  const Eigen::Vector2d d = dij(fi, fj, jr);
  jac[0][0] = -2 * d.x();
  jac[0][1] = -2 * d.y();
  jac[0][2] = -2 * d.dot(fi.B * jr.si);
  jac[0][3] = 2 * d.x();
  jac[0][4] = 2 * d.y();
  jac[0][5] = 2 * d.dot(fj.B * jr.sj);
}
inline void distance_gamma(const JointRecord& jr, const Frame& fi, const Frame& fj, double* out) {
  const Eigen::Vector2d d = dij(fi, fj, jr), dd = ddij(fi, fj, jr);
  const Eigen::Vector2d ai = centripetal(fi, jr.si), aj = centripetal(fj, jr.sj);
  out[0] = -2 * dd.dot(dd) + 2 * d.dot(aj - ai) + (jr.is_driver ? 2 * jr.rate * jr.rate : 0.0);
}
inline double distance_rate(const JointRecord& jr, double f) { return 2 * f * jr.rate; }

// absolute_x / absolute_y: r_i + A_i s - f = 0 in component C.
template <int C>
void absolute_phi(const JointRecord& jr, const Frame& fi, const Frame&, double f, double* out) {
  out[0] = fi.r[C] + (fi.A * jr.si)[C] - f;
}
template <int C>
void absolute_jacobian(const JointRecord& jr, const Frame& fi, const Frame&, double (*jac)[6]) {
  jac[0][C] = 1;
  jac[0][2] = (fi.B * jr.si)[C];
}
template <int C>
void absolute_gamma(const JointRecord& jr, const Frame& fi, const Frame&, double* out) {
  out[0] = (fi.A * jr.si)[C] * fi.w * fi.w;
}

// absolute_angle: phi_i - f = 0; relative_angle: phi_j - phi_i - f = 0.
inline void absolute_angle_phi(const JointRecord&, const Frame& fi, const Frame&, double f,
                               double* out) {
  out[0] = fi.phi - f;
}
inline void absolute_angle_jacobian(const JointRecord&, const Frame&, const Frame&,
                                    double (*jac)[6]) {
  jac[0][2] = 1;
}
inline void relative_angle_phi(const JointRecord&, const Frame& fi, const Frame& fj, double f,
                               double* out) {
  out[0] = fj.phi - fi.phi - f;
}
inline void relative_angle_jacobian(const JointRecord&, const Frame&, const Frame&,
                                    double (*jac)[6]) {
  jac[0][2] = -1;
  jac[0][5] = 1;
}
inline void zero_gamma(const JointRecord&, const Frame&, const Frame&, double* out) { out[0] = 0; }

}  // namespace joints

// The generic library: the types it can evaluate (a mechanism with any other type, such as
// `expression`, is not compared against it).
inline const JointFormulas* find_joint_formulas(const std::string& type) {
  using namespace joints;
  static const JointFormulas kLibrary[] = {
      {"revolute", 2, revolute_phi, revolute_jacobian, revolute_gamma, rate},
      {"translational", 2, slider_phi, slider_jacobian, slider_gamma, rate},
      {"distance", 1, distance_phi, distance_jacobian, distance_gamma, distance_rate},
      {"revolute_translational", 1, slider_phi, slider_jacobian, slider_gamma, rate},
      {"absolute_x", 1, absolute_phi<0>, absolute_jacobian<0>, absolute_gamma<0>, rate},
      {"absolute_y", 1, absolute_phi<1>, absolute_jacobian<1>, absolute_gamma<1>, rate},
      {"absolute_angle", 1, absolute_angle_phi, absolute_angle_jacobian, zero_gamma, rate},
      {"relative_angle", 1, relative_angle_phi, relative_angle_jacobian, zero_gamma, rate},
  };
  for (const auto& f : kLibrary)
    if (type == f.type) return &f;
  return nullptr;
}

struct MechanismData {
  int bodies = 0;
  std::vector<JointRecord> joints;  // joints then drivers: the rows of Phi in this order
  Eigen::VectorXd q0;
  double length_scale = 1;

  int nq() const { return 3 * bodies; }
  int nc() const {
    int n = 0;
    for (const auto& jr : joints) n += jr.equation_count();
    return n;
  }
};

// Evaluates Phi, Phi_q (dense), nu and gamma of a MechanismData.
class GenericSystem {
 public:
  using Scalar = double;
  static constexpr int kNq = Eigen::Dynamic;
  static constexpr int kNc = Eigen::Dynamic;

  explicit GenericSystem(MechanismData data) : data_(std::move(data)) {}

  int nq() const { return data_.nq(); }
  int nc() const { return data_.nc(); }
  double length_scale() const { return data_.length_scale; }
  const MechanismData& data() const { return data_; }

  void phi(const double* q, double t, double* out) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      const Frame fi = Frame::of(q, nullptr, jr.i), fj = Frame::of(q, nullptr, jr.j);
      jr.formulas->phi(jr, fi, fj, jr.value + jr.rate * t, out + row);
      row += jr.equation_count();
    }
  }

  // Dense Phi_q; every entry a joint does not touch is left as it is (zero from the workspace).
  template <class M>
  void jacobian(const double* q, double /*t*/, M& jac) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      const Frame fi = Frame::of(q, nullptr, jr.i), fj = Frame::of(q, nullptr, jr.j);
      double d[2][6] = {};
      jr.formulas->jacobian(jr, fi, fj, d);
      for (int r = 0; r < jr.equation_count(); ++r)
        for (int c = 0; c < 3; ++c) {
          if (jr.i != kGround) jac(row + r, 3 * jr.i + c) = d[r][c];
          if (jr.j != kGround) jac(row + r, 3 * jr.j + c) = d[r][3 + c];
        }
      row += jr.equation_count();
    }
  }

  // nu = -Phi_t: only drivers depend on t.
  void nu(const double* /*q*/, double t, double* out) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      for (int k = 0; k < jr.equation_count(); ++k) out[row + k] = 0;
      if (jr.is_driver) {
        const int last = row + jr.equation_count() - 1;  // the driven equation
        out[last] = jr.formulas->driven_rate(jr, jr.value + jr.rate * t);
      }
      row += jr.equation_count();
    }
  }

  // gamma = -(second derivative of Phi along (qd, 1)), per joint in closed form.
  void gamma(const double* q, const double* qd, double /*t*/, double* out) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      const Frame fi = Frame::of(q, qd, jr.i), fj = Frame::of(q, qd, jr.j);
      jr.formulas->gamma(jr, fi, fj, out + row);
      row += jr.equation_count();
    }
  }

 private:
  MechanismData data_;
};

// The generic solver: kinegen's Newton / LU on run-time sizes over the generic system.
using GenericSolver = BasicSolver<GenericSystem>;

}  // namespace kinegen::generic

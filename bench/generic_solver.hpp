// A plain generic kinematic solver, the way DADS-style programs work: the mechanism is data
// (bodies, joint records with numbers, drivers f(t) = value + rate * t), and Phi, Phi_q, nu and
// gamma are assembled at run time by loops over the joint records, with the analytic formulas
// of Haug's planar joint library. No code generation, no symbolic algebra; dense LU (Eigen).
//
// It plugs into kinegen::BasicSolver as a System (dynamic sizes), so a comparison against the
// generated code runs the very same Newton iteration and LU: only the evaluation differs.
// Depends on Eigen and kinegen/solver.hpp only, so other benchmarks can reuse it.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <kinegen/solver.hpp>
#include <vector>

namespace kinegen::generic {

enum class JointType {
  kRevolute,
  kTranslational,
  kDistance,
  kRevoluteTranslational,
  kAbsoluteX,
  kAbsoluteY,
  kAbsoluteAngle,
  kRelativeAngle,
};

inline constexpr int kGround = -1;

// One joint or driver as numbers. `value` is the constant of a joint (value, length, angle);
// a driver uses f(t) = value + rate * t in its place.
struct JointRecord {
  JointType type = JointType::kRevolute;
  int i = kGround, j = kGround;  // body indices (absolute_*: the body is i)
  Eigen::Vector2d si = Eigen::Vector2d::Zero(), sj = Eigen::Vector2d::Zero();
  Eigen::Vector2d vi = Eigen::Vector2d::UnitX();
  double value = 0, rate = 0;
  bool is_driver = false;

  int equation_count() const {
    return type == JointType::kRevolute || type == JointType::kTranslational ? 2 : 1;
  }
};

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
      const Frame fi = frame(q, nullptr, jr.i), fj = frame(q, nullptr, jr.j);
      const double f = jr.value + jr.rate * t;
      switch (jr.type) {
        case JointType::kRevolute: {
          const Eigen::Vector2d d = dij(fi, fj, jr);
          out[row++] = d.x();
          out[row++] = d.y();
          break;
        }
        case JointType::kTranslational:
        case JointType::kRevoluteTranslational:
          out[row++] = (fi.B * jr.vi).dot(dij(fi, fj, jr));
          if (jr.type == JointType::kTranslational) out[row++] = fj.phi - fi.phi - f;
          break;
        case JointType::kDistance: {
          const Eigen::Vector2d d = dij(fi, fj, jr);
          out[row++] = d.dot(d) - f * f;
          break;
        }
        case JointType::kAbsoluteX:
          out[row++] = fi.r.x() + (fi.A * jr.si).x() - f;
          break;
        case JointType::kAbsoluteY:
          out[row++] = fi.r.y() + (fi.A * jr.si).y() - f;
          break;
        case JointType::kAbsoluteAngle:
          out[row++] = fi.phi - f;
          break;
        case JointType::kRelativeAngle:
          out[row++] = fj.phi - fi.phi - f;
          break;
      }
    }
  }

  // Dense Phi_q; every entry a joint does not touch is left as it is (zero from the workspace).
  template <class M>
  void jacobian(const double* q, double /*t*/, M& jac) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      const Frame fi = frame(q, nullptr, jr.i), fj = frame(q, nullptr, jr.j);
      switch (jr.type) {
        case JointType::kRevolute: {
          // d_ij = r_j + A_j sj - r_i - A_i si
          const Eigen::Vector2d bi = fi.B * jr.si, bj = fj.B * jr.sj;
          for (int c = 0; c < 2; ++c) {
            if (jr.i != kGround) {
              jac(row + c, 3 * jr.i + c) = -1;
              jac(row + c, 3 * jr.i + 2) = -bi[c];
            }
            if (jr.j != kGround) {
              jac(row + c, 3 * jr.j + c) = 1;
              jac(row + c, 3 * jr.j + 2) = bj[c];
            }
          }
          row += 2;
          break;
        }
        case JointType::kTranslational:
        case JointType::kRevoluteTranslational: {
          // n = B_i vi = (A_i vi)^perp, dn/dphi_i = -A_i vi
          const Eigen::Vector2d n = fi.B * jr.vi, d = dij(fi, fj, jr);
          if (jr.i != kGround) {
            jac(row, 3 * jr.i) = -n.x();
            jac(row, 3 * jr.i + 1) = -n.y();
            jac(row, 3 * jr.i + 2) = -(fi.A * jr.vi).dot(d) - n.dot(fi.B * jr.si);
          }
          if (jr.j != kGround) {
            jac(row, 3 * jr.j) = n.x();
            jac(row, 3 * jr.j + 1) = n.y();
            jac(row, 3 * jr.j + 2) = n.dot(fj.B * jr.sj);
          }
          ++row;
          if (jr.type == JointType::kTranslational) {
            if (jr.i != kGround) jac(row, 3 * jr.i + 2) = -1;
            if (jr.j != kGround) jac(row, 3 * jr.j + 2) = 1;
            ++row;
          }
          break;
        }
        case JointType::kDistance: {
          const Eigen::Vector2d d = dij(fi, fj, jr);
          if (jr.i != kGround) {
            jac(row, 3 * jr.i) = -2 * d.x();
            jac(row, 3 * jr.i + 1) = -2 * d.y();
            jac(row, 3 * jr.i + 2) = -2 * d.dot(fi.B * jr.si);
          }
          if (jr.j != kGround) {
            jac(row, 3 * jr.j) = 2 * d.x();
            jac(row, 3 * jr.j + 1) = 2 * d.y();
            jac(row, 3 * jr.j + 2) = 2 * d.dot(fj.B * jr.sj);
          }
          ++row;
          break;
        }
        case JointType::kAbsoluteX:
        case JointType::kAbsoluteY: {
          const int c = jr.type == JointType::kAbsoluteX ? 0 : 1;
          jac(row, 3 * jr.i + c) = 1;
          jac(row, 3 * jr.i + 2) = (fi.B * jr.si)[c];
          ++row;
          break;
        }
        case JointType::kAbsoluteAngle:
          jac(row++, 3 * jr.i + 2) = 1;
          break;
        case JointType::kRelativeAngle:
          if (jr.i != kGround) jac(row, 3 * jr.i + 2) = -1;
          if (jr.j != kGround) jac(row, 3 * jr.j + 2) = 1;
          ++row;
          break;
      }
    }
  }

  // nu = -Phi_t: only drivers depend on t.
  void nu(const double* /*q*/, double t, double* out) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      for (int k = 0; k < jr.equation_count(); ++k) out[row + k] = 0;
      if (jr.is_driver) {
        const double f = jr.value + jr.rate * t;
        const int last = row + jr.equation_count() - 1;  // the driven equation
        out[last] = jr.type == JointType::kDistance ? 2 * f * jr.rate : jr.rate;
      }
      row += jr.equation_count();
    }
  }

  // gamma = -(second derivative of Phi along (qd, 1)), per joint in closed form.
  void gamma(const double* q, const double* qd, double t, double* out) const {
    int row = 0;
    for (const auto& jr : data_.joints) {
      const Frame fi = frame(q, qd, jr.i), fj = frame(q, qd, jr.j);
      const double f = jr.value + jr.rate * t;
      // d'' along qd: -A_j sj w_j^2 + A_i si w_i^2
      const Eigen::Vector2d ai = fi.A * jr.si * (fi.w * fi.w), aj = fj.A * jr.sj * (fj.w * fj.w);
      switch (jr.type) {
        case JointType::kRevolute: {
          const Eigen::Vector2d g = aj - ai;
          out[row++] = g.x();
          out[row++] = g.y();
          break;
        }
        case JointType::kTranslational:
        case JointType::kRevoluteTranslational: {
          const Eigen::Vector2d n = fi.B * jr.vi, d = dij(fi, fj, jr), dd = ddij(fi, fj, jr);
          out[row++] = fi.w * fi.w * n.dot(d) + 2 * fi.w * (fi.A * jr.vi).dot(dd) + n.dot(aj - ai);
          if (jr.type == JointType::kTranslational) out[row++] = 0;
          break;
        }
        case JointType::kDistance: {
          const Eigen::Vector2d d = dij(fi, fj, jr), dd = ddij(fi, fj, jr);
          out[row++] =
              -2 * dd.dot(dd) + 2 * d.dot(aj - ai) + (jr.is_driver ? 2 * jr.rate * jr.rate : 0.0);
          (void)f;
          break;
        }
        case JointType::kAbsoluteX:
          out[row++] = (fi.A * jr.si).x() * fi.w * fi.w;
          break;
        case JointType::kAbsoluteY:
          out[row++] = (fi.A * jr.si).y() * fi.w * fi.w;
          break;
        case JointType::kAbsoluteAngle:
        case JointType::kRelativeAngle:
          out[row++] = 0;
          break;
      }
    }
  }

 private:
  // A body's position, rotation, its derivative dA/dphi, and velocities (ground: all zero).
  struct Frame {
    Eigen::Vector2d r = Eigen::Vector2d::Zero(), v = Eigen::Vector2d::Zero();
    double phi = 0, w = 0;
    Eigen::Matrix2d A = Eigen::Matrix2d::Identity(), B = Eigen::Matrix2d::Zero();
  };

  static Frame frame(const double* q, const double* qd, int body) {
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
  static Eigen::Vector2d dij(const Frame& fi, const Frame& fj, const JointRecord& jr) {
    return fj.r + fj.A * jr.sj - fi.r - fi.A * jr.si;
  }
  // d_ij' along qd
  static Eigen::Vector2d ddij(const Frame& fi, const Frame& fj, const JointRecord& jr) {
    return fj.v + fj.B * jr.sj * fj.w - fi.v - fi.B * jr.si * fi.w;
  }

  MechanismData data_;
};

// The generic solver: kinegen's Newton / LU on run-time sizes over the generic system.
using GenericSolver = BasicSolver<GenericSystem>;

}  // namespace kinegen::generic

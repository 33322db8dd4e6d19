// A hand-written loop-closure solver of examples/spatial/double_wishbone.yaml, independent of
// kinegen's equations: three unknowns, the lower arm's angle th1 about its pivot axis, the
// upper arm's th2 about its own, and the upright's turn psi about the line through its two
// ball joints (after the shortest rotation that carries that line from its design direction to
// where the arms put it). Three scalar closure equations: the ball joints' distance, the tie
// rod's length, the wheel centre's height against the driver. Newton on the 3x3 system from the
// previous solution; velocities and accelerations from the same 3x3 Jacobian, the time
// derivatives by second-order forward jets (exact, no differences).
#pragma once

#include <Eigen/Dense>
#include <cmath>

namespace kinegen::bench {

// f, f' and f'' along one direction s: enough for Jacobian columns, velocities and
// accelerations of every closed form below.
struct Jet {
  double v = 0, d = 0, dd = 0;
  Jet() = default;
  Jet(double value) : v(value) {}  // NOLINT: constants mix freely
  Jet(double value, double first, double second) : v(value), d(first), dd(second) {}
};
inline Jet operator+(Jet a, Jet b) { return {a.v + b.v, a.d + b.d, a.dd + b.dd}; }
inline Jet operator-(Jet a, Jet b) { return {a.v - b.v, a.d - b.d, a.dd - b.dd}; }
inline Jet operator-(Jet a) { return {-a.v, -a.d, -a.dd}; }
inline Jet operator*(Jet a, Jet b) {
  return {a.v * b.v, a.d * b.v + a.v * b.d, a.dd * b.v + 2 * a.d * b.d + a.v * b.dd};
}
// phi(a) given phi, phi' and phi'' at a.v
inline Jet chain(Jet a, double f, double f1, double f2) {
  return {f, f1 * a.d, f2 * a.d * a.d + f1 * a.dd};
}
inline Jet operator/(Jet a, Jet b) {
  const double r = 1 / b.v;
  return a * chain(b, r, -r * r, 2 * r * r * r);
}
inline Jet sqrt(Jet a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, 0.5 / s, -0.25 / (s * a.v));
}
inline Jet sin(Jet a) { return chain(a, std::sin(a.v), std::cos(a.v), -std::sin(a.v)); }
inline Jet cos(Jet a) { return chain(a, std::cos(a.v), -std::sin(a.v), -std::cos(a.v)); }
inline Jet asin(Jet a) {
  const double w = 1 - a.v * a.v, r = 1 / std::sqrt(w);
  return chain(a, std::asin(a.v), r, a.v * r / w);
}
inline Jet atan2(Jet y, Jet x) {
  // atan(y/x) + branch: derivatives from the quotient, the value from std::atan2.
  const Jet q = y / x;
  const double w = 1 / (1 + q.v * q.v);
  Jet a = chain(q, 0, w, -2 * q.v * w * w);
  a.v = std::atan2(y.v, x.v);
  return a;
}

struct V3 {
  Jet x, y, z;
};
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(Jet s, const V3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline Jet dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline V3 v3(double x, double y, double z) { return {x, y, z}; }
// Rodrigues: v turned by angle c, s (cos, sin) about the unit axis k.
inline V3 turn(const V3& k, Jet c, Jet s, const V3& v) {
  return c * v + s * cross(k, v) + ((Jet(1) - c) * dot(k, v)) * k;
}

class DoubleWishboneHand {
 public:
  // The solution's unknowns and what the step reports.
  struct State {
    Eigen::Vector3d x = Eigen::Vector3d::Zero(), xd = Eigen::Vector3d::Zero(),
                    xdd = Eigen::Vector3d::Zero();
    // W (wheel centre), then toe, camber, caster, kpi: value, rate, acceleration.
    double w[3][3], angles[4][3];
  };

  explicit DoubleWishboneHand(double travel = 0.08, double rack = 0) : travel_(travel) {
    rack_point_ = v3(-0.14, 0.33 + rack, 0.21);
  }

  // Position, velocity, acceleration and the outputs at t; Newton from s.x. False when Newton
  // fails to converge or the closure residual stays above tolerance.
  bool step(double t, State& s) const {
    Eigen::Matrix3d jac;
    Eigen::Vector3d g;
    for (int it = 0;; ++it) {
      residual_and_jacobian(s.x, t, g, jac);
      const Eigen::Vector3d dx = jac.partialPivLu().solve(g);
      s.x -= dx;
      if (!std::isfinite(dx.squaredNorm()) || it == 20) return false;
      if (dx.cwiseAbs().maxCoeff() < 1e-12) break;
    }
    residual_and_jacobian(s.x, t, g, jac);
    if (!(g.cwiseAbs().maxCoeff() < 1e-12)) return false;  // lengths, metres (squared / m)
    const auto lu = jac.partialPivLu();
    if (!(std::abs(lu.determinant()) > 1e-12)) return false;  // conditioning: near a singularity
    // g_x xd + g_t = 0, then g_x xdd + (second derivative of g along (xd, 1) at xdd = 0) = 0.
    Jet gs[3];
    eval(s.x, Eigen::Vector3d::Zero(), t, 1, gs, nullptr);
    s.xd = -lu.solve(Eigen::Vector3d(gs[0].d, gs[1].d, gs[2].d));
    eval(s.x, s.xd, t, 1, gs, nullptr);
    s.xdd = -lu.solve(Eigen::Vector3d(gs[0].dd, gs[1].dd, gs[2].dd));
    Outputs out;
    eval(s.x, s.xd, t, 1, gs, &out, &s.xdd);
    const Jet* w[3] = {&out.w.x, &out.w.y, &out.w.z};
    for (int i = 0; i < 3; ++i) s.w[i][0] = w[i]->v, s.w[i][1] = w[i]->d, s.w[i][2] = w[i]->dd;
    for (int i = 0; i < 4; ++i)
      s.angles[i][0] = out.angles[i].v, s.angles[i][1] = out.angles[i].d,
      s.angles[i][2] = out.angles[i].dd;
    return true;
  }

 private:
  struct Outputs {
    V3 w;
    Jet angles[4];
  };

  // The closure residuals along x + s xd (+ s^2/2 xdd), t + s tr; the outputs when asked.
  void eval(const Eigen::Vector3d& x, const Eigen::Vector3d& xd, double t, double tr, Jet* g,
            Outputs* out, const Eigen::Vector3d* xdd = nullptr) const {
    Jet th[3];
    for (int k = 0; k < 3; ++k) th[k] = Jet(x[k], xd[k], xdd ? (*xdd)[k] : 0.0);
    const V3 lower_pivot = v3(0.22, 0.30, 0.14), upper_pivot = v3(0.12, 0.42, 0.47);
    const V3 lbj0 = v3(0.005, 0.72, 0.13), ubj0 = v3(-0.015, 0.67, 0.49);
    const V3 lbj = lower_pivot + turn(axis1_, cos(th[0]), sin(th[0]), lbj0 - lower_pivot);
    const V3 ubj = upper_pivot + turn(axis2_, cos(th[1]), sin(th[1]), ubj0 - upper_pivot);
    const V3 d = ubj - lbj, d0 = ubj0 - lbj0;
    const Jet len2 = dot(d, d), len = sqrt(len2);
    const V3 k = (Jet(1) / len) * d, k0 = (Jet(1) / sqrt(dot(d0, d0))) * d0;
    // The shortest rotation carrying k0 to k, then psi about k.
    const V3 c = cross(k0, k);
    const Jet cosa = dot(k0, k);
    auto place = [&](const V3& v0) {
      const V3 v = cosa * v0 + cross(c, v0) + (dot(c, v0) / (Jet(1) + cosa)) * c;
      return turn(k, cos(th[2]), sin(th[2]), v);
    };
    const V3 tie = lbj + place(v3(-0.13, 0.70, 0.22) - lbj0) - rack_point_;
    const V3 w = lbj + place(v3(0, 0.76, 0.30) - lbj0);
    const Jet time(t, tr, 0);
    g[0] = Jet(0.5) * (len2 - dot(d0, d0));
    g[1] = Jet(0.5) * (dot(tie, tie) - kTieRod2);
    g[2] = w.z - (Jet(0.30) + Jet(travel_) * (Jet(2) * time - Jet(1)));
    if (out == nullptr) return;
    const V3 spin = place(v3(0, 1, 0));
    out->w = w;
    out->angles[0] = atan2(spin.x, spin.y);  // toe (left side, sigma = +1)
    out->angles[1] = -asin(spin.z);          // camber
    out->angles[2] = atan2(-k.x, k.z);       // caster
    out->angles[3] = atan2(-k.y, k.z);       // kingpin inclination
  }

  void residual_and_jacobian(const Eigen::Vector3d& x, double t, Eigen::Vector3d& g,
                             Eigen::Matrix3d& jac) const {
    Jet gs[3];
    for (int col = 0; col < 3; ++col) {
      eval(x, Eigen::Vector3d::Unit(col), t, 0, gs, nullptr);
      for (int r = 0; r < 3; ++r) jac(r, col) = gs[r].d;
    }
    g = Eigen::Vector3d(gs[0].v, gs[1].v, gs[2].v);
  }

  static V3 unit(double x, double y, double z) {
    const double n = std::sqrt(x * x + y * y + z * z);
    return v3(x / n, y / n, z / n);
  }

  static constexpr double kTieRod2 = 0.01 * 0.01 + 0.37 * 0.37 + 0.01 * 0.01;
  double travel_;
  V3 rack_point_;
  V3 axis1_ = unit(-0.44, 0.02, 0.02), axis2_ = unit(-0.28, 0.01, -0.02);
};

}  // namespace kinegen::bench

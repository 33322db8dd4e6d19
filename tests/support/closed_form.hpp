// Closed-form (hand-derived) kinematics of the example mechanisms in examples/,
// used as reference solutions by the tests.
//
// Every function returns the exact state at time t: q, qd, qdd in the body order and
// body-frame conventions of the corresponding YAML file ([x, y, phi] per body).
// Positions come from law of cosines / atan2 / asin; velocities and accelerations are
// their analytic time derivatives (no numerical differentiation). The crank angle is
// omega*t exactly (constant omega) and every other angle is continuous in t from its
// t = 0 value on the documented assembly branch, i.e. what a Newton solver tracking
// from the YAML's q0 gives (no wrapping to (-pi, pi]).
//
// Header-only, C++17, <cmath> and <array> only.
#ifndef KINEGEN_TESTS_SUPPORT_CLOSED_FORM_HPP
#define KINEGEN_TESTS_SUPPORT_CLOSED_FORM_HPP

#include <array>
#include <cmath>

namespace kinegen::closed_form {

template <int N>
struct State {
    std::array<double, N> q{}, qd{}, qdd{};
};

// Position, velocity and acceleration of a point in the global frame.
struct PointState {
    std::array<double, 2> r{}, v{}, a{};
};

// Point fixed at local s in body `body` (0-based, file order) of a state:
//   r = r_i + A s,  v = rd_i + w (A s)^perp,  a = rdd_i + wd (A s)^perp - w^2 A s.
template <int N>
inline PointState point_state(const State<N>& st, int body, double sx, double sy) {
    const int k = 3 * body;
    const double phi = st.q[k + 2], w = st.qd[k + 2], wd = st.qdd[k + 2];
    const double c = std::cos(phi), s = std::sin(phi);
    const double ax = c * sx - s * sy, ay = s * sx + c * sy;  // A s
    const double px = -ay, py = ax;                           // (A s)^perp
    PointState p;
    p.r = {st.q[k] + ax, st.q[k + 1] + ay};
    p.v = {st.qd[k] + w * px, st.qd[k + 1] + w * py};
    p.a = {st.qdd[k] + wd * px - w * w * ax, st.qdd[k + 1] + wd * py - w * w * ay};
    return p;
}

// ---------------------------------------------------------------------------------------
// Lecture slider-crank (Haug, Example 3.1): examples/slider_crank_lecture.yaml and
// examples/slider_crank.yaml (identical Phi). Bodies: crank, rod (nq = 6).
//   Phi = [x1; y1; x1 - x2 + cos phi1 + l sin phi2; y1 - y2 + sin phi1 - l cos phi2; y2;
//          phi1 - omega t]
// crank: length 1, origin at the ground pivot. rod: origin at the slider (on the x axis),
// rod-local [0, l] pinned to the crank tip.
// Branch: slider on the +x side, phi_rod = acos(sin(phi1) / l) in (0, pi) (pi/2 at t = 0),
// x_rod = cos phi1 + l sin phi_rod. Requires l > 1.
struct SliderCrankLectureParams {
    double l = 2.0;
    double omega = 1.0;
};

inline State<6> slider_crank_lecture_state(double t, const SliderCrankLectureParams& p = {}) {
    const double w = p.omega, l = p.l;
    const double p1 = w * t, s1 = std::sin(p1), c1 = std::cos(p1);
    const double cp2 = s1 / l;                    // cos phi2 = sin phi1 / l
    const double p2 = std::acos(cp2);
    const double sp2 = std::sin(p2);              // > 0 on this branch
    // d/dt: -sin phi2 * w2 = cos phi1 * w / l
    const double w2 = -c1 * w / (l * sp2);
    // d2/dt2: -cos phi2 w2^2 - sin phi2 a2 = -sin phi1 w^2 / l
    const double a2 = (s1 * w * w / l - cp2 * w2 * w2) / sp2;
    const double x2 = c1 + l * sp2;
    const double v2 = -s1 * w + l * cp2 * w2;
    const double ax2 = -c1 * w * w - l * sp2 * w2 * w2 + l * cp2 * a2;
    State<6> st;
    st.q = {0.0, 0.0, p1, x2, 0.0, p2};
    st.qd = {0.0, 0.0, w, v2, 0.0, w2};
    st.qdd = {0.0, 0.0, 0.0, ax2, 0.0, a2};
    return st;
}

// examples/slider_crank.yaml is the same mechanism with library joints.
using SliderCrankParams = SliderCrankLectureParams;
inline State<6> slider_crank_state(double t, const SliderCrankParams& p = {}) {
    return slider_crank_lecture_state(t, p);
}

// ---------------------------------------------------------------------------------------
// Offset slider-crank: examples/offset_slider_crank.yaml. Bodies: crank, rod, slider (nq = 9).
// crank: origin at O = (0,0), x along O->A (length r); rod: origin at A, x along A->B
// (length l); slider: origin at B on the line y = e, phi = 0.
// Branch: slider to the right of A: phi_rod = asin((e - r sin phi1) / l) in (-pi/2, pi/2),
// x_B = r cos phi1 + l cos phi_rod. Requires l > r + |e|.
struct OffsetSliderCrankParams {
    double r = 1.0;
    double l = 3.0;
    double e = 0.5;
    double omega = 1.0;
};

inline State<9> offset_slider_crank_state(double t, const OffsetSliderCrankParams& p = {}) {
    const double w = p.omega, r = p.r, l = p.l, e = p.e;
    const double p1 = w * t, s1 = std::sin(p1), c1 = std::cos(p1);
    const double sp2 = (e - r * s1) / l;          // sin phi2
    const double p2 = std::asin(sp2);
    const double cp2 = std::cos(p2);              // > 0 on this branch
    // d/dt: cos phi2 w2 = -r cos phi1 w / l
    const double w2 = -r * c1 * w / (l * cp2);
    // d2/dt2: -sin phi2 w2^2 + cos phi2 a2 = r sin phi1 w^2 / l
    const double a2 = (r * s1 * w * w / l + sp2 * w2 * w2) / cp2;
    const double xa = r * c1, ya = r * s1;
    const double vxa = -r * s1 * w, vya = r * c1 * w;
    const double axa = -r * c1 * w * w, aya = -r * s1 * w * w;
    const double xb = xa + l * cp2;
    const double vxb = vxa - l * sp2 * w2;
    const double axb = axa - l * cp2 * w2 * w2 - l * sp2 * a2;
    State<9> st;
    st.q = {0.0, 0.0, p1, xa, ya, p2, xb, e, 0.0};
    st.qd = {0.0, 0.0, w, vxa, vya, w2, vxb, 0.0, 0.0};
    st.qdd = {0.0, 0.0, 0.0, axa, aya, a2, axb, 0.0, 0.0};
    return st;
}

// ---------------------------------------------------------------------------------------
// Four-bar (Grashof crank-rocker): examples/four_bar.yaml. Bodies: crank, coupler, rocker
// (nq = 9). Ground pivots O2 = (0,0), O4 = (d,0).
// crank: origin O2, x along O2->A (a); coupler: origin A, x along A->B (b), coupler point
// P at coupler-local [px, py]; rocker: origin O4, x along O4->B (c).
// Branch ("open", B above the line A-O4): with D = O4 - A, delta = |D|,
//   theta = atan2(-a sin phi1, d - a cos phi1)                (continuous: d > a)
//   alpha = acos((b^2 + delta^2 - c^2) / (2 b delta))        (angle at A, in (0, pi))
//   beta  = acos((c^2 + delta^2 - b^2) / (2 c delta))        (angle at O4, in (0, pi))
//   phi_coupler = theta + alpha,  phi_rocker = theta + pi - beta.
// Velocities/accelerations from the differentiated loop equation
//   a e^{i phi1} + b e^{i phi2} - c e^{i phi3} - d = 0.
struct FourBarParams {
    double a = 1.0;
    double b = 3.5;
    double c = 2.5;
    double d = 3.0;
    double px = 1.5;
    double py = 1.0;
    double omega = 1.0;
};

inline State<9> four_bar_state(double t, const FourBarParams& p = {}) {
    const double w1 = p.omega, a = p.a, b = p.b, c = p.c, d = p.d;
    const double p1 = w1 * t, s1 = std::sin(p1), c1 = std::cos(p1);
    const double dx = d - a * c1, dy = -a * s1;
    const double del2 = dx * dx + dy * dy, del = std::sqrt(del2);
    const double theta = std::atan2(dy, dx);
    const double alpha = std::acos((b * b + del2 - c * c) / (2.0 * b * del));
    const double beta = std::acos((c * c + del2 - b * b) / (2.0 * c * del));
    const double p2 = theta + alpha;
    const double p3 = theta + std::acos(-1.0) - beta;
    const double s12 = std::sin(p1 - p2), c12 = std::cos(p1 - p2);
    const double s13 = std::sin(p1 - p3), c13 = std::cos(p1 - p3);
    const double s23 = std::sin(p2 - p3), c23 = std::cos(p2 - p3);
    const double s32 = -s23, c32 = c23;
    // velocity: (loop eq. * e^{-i phi3}).re and (* e^{-i phi2}).re
    const double w2 = -a * w1 * s13 / (b * s23);
    const double w3 = a * w1 * s12 / (c * s32);
    const double al1 = 0.0;
    const double al2 = (-a * al1 * s13 - a * w1 * w1 * c13 - b * w2 * w2 * c23 + c * w3 * w3) / (b * s23);
    const double al3 = (a * al1 * s12 + a * w1 * w1 * c12 + b * w2 * w2 - c * w3 * w3 * c32) / (c * s32);
    State<9> st;
    st.q = {0.0, 0.0, p1, a * c1, a * s1, p2, d, 0.0, p3};
    st.qd = {0.0, 0.0, w1, -a * s1 * w1, a * c1 * w1, w2, 0.0, 0.0, w3};
    st.qdd = {0.0, 0.0, al1,
              -a * s1 * al1 - a * c1 * w1 * w1, a * c1 * al1 - a * s1 * w1 * w1, al2,
              0.0, 0.0, al3};
    return st;
}

// Coupler point P (coupler-local [px, py]).
inline PointState four_bar_coupler_point(double t, const FourBarParams& p = {}) {
    return point_state(four_bar_state(t, p), 1, p.px, p.py);
}

// ---------------------------------------------------------------------------------------
// Quick-return (crank-shaper, oscillating slotted rocker): examples/quick_return.yaml.
// Bodies: crank, rocker, block (nq = 9).
// crank: origin O2 = (0,0), x along O2->A (r); rocker: origin O4 = (0,-d), x along the
// slot; block: origin at the crank pin A, phi_block = phi_rocker.
// Unique assembly (r < d): phi_rocker = atan2(d + r sin phi1, r cos phi1) in (0, pi).
//   rho^2 = |O4 A|^2 = r^2 + d^2 + 2 r d sin phi1
//   w3 = omega r (r + d sin phi1) / rho^2,  a3 = omega^2 r d (d^2 - r^2) cos phi1 / rho^4.
struct QuickReturnParams {
    double r = 1.0;
    double d = 2.0;
    double L = 4.0;
    double omega = 1.0;
};

inline State<9> quick_return_state(double t, const QuickReturnParams& p = {}) {
    const double w = p.omega, r = p.r, d = p.d;
    const double p1 = w * t, s1 = std::sin(p1), c1 = std::cos(p1);
    const double rho2 = r * r + d * d + 2.0 * r * d * s1;
    const double p3 = std::atan2(d + r * s1, r * c1);
    const double w3 = w * r * (r + d * s1) / rho2;
    const double a3 = w * w * r * d * (d * d - r * r) * c1 / (rho2 * rho2);
    const double xa = r * c1, ya = r * s1;
    const double vxa = -r * s1 * w, vya = r * c1 * w;
    const double axa = -r * c1 * w * w, aya = -r * s1 * w * w;
    State<9> st;
    st.q = {0.0, 0.0, p1, 0.0, -d, p3, xa, ya, p3};
    st.qd = {0.0, 0.0, w, 0.0, 0.0, w3, vxa, vya, w3};
    st.qdd = {0.0, 0.0, 0.0, 0.0, 0.0, a3, axa, aya, a3};
    return st;
}

}  // namespace kinegen::closed_form

#endif  // KINEGEN_TESTS_SUPPORT_CLOSED_FORM_HPP

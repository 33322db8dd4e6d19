// Time per full step of the double wishbone (examples/spatial/double_wishbone.yaml: position to
// the solver's tolerance, velocity, acceleration and the suspension outputs with their rates),
// three ways, interleaved in this one process over the same wheel-travel grid (t from 0 to 1,
// the wheel centre from -80 to +80 mm):
//
//   generated  kinegen::Solver<Model>::step (the generated block solver with its Taylor
//              predictor) and Model::outputs: every output, .v and .a
//   dense      kinegen::DenseSolver<Model>: a generic dense Newton, one LU of the whole 28 x 28
//              Phi_q (the header's phi and phi_q, evaluated as a black box), then the dense
//              velocity and acceleration solves, and Model::outputs
//   hand       bench/double_wishbone_hand.hpp: a hand-written loop closure on three angles
//              (not kinegen's equations), its own W, toe, camber, caster and kpi with rates
//
// Before timing, the hand-written solver is checked against the generated step at a few times
// (not timed). The best chunk of each counts; ratios come from the same run. Not a test.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <kinegen/solver.hpp>

#include "best_of_chunks.hpp"
#include "double_wishbone.hpp"
#include "double_wishbone_hand.hpp"

namespace {

using Model = kinegen::models::double_wishbone;
using Hand = kinegen::bench::DoubleWishboneHand;

constexpr int kChunk = 500;
constexpr int kChunks = 60;
constexpr double kDt = 1.0 / (kChunk * kChunks);
constexpr int kUpright = 14;           // the upright's r, then its Euler parameters
constexpr int kToe = 1, kWheelZ = 10;  // toe, camber, caster, kpi follow toe

double g_checksum = 0;

// The wheel centre (design position 0, 0.76, 0.30 in the upright's frame) from q.
void wheel_centre(const double* q, double w[3]) {
  const double* r = q + kUpright;
  const double e0 = r[3], e1 = r[4], e2 = r[5], e3 = r[6];
  const double s[3] = {0, 0.76, 0.30};
  const double a[3][3] = {{e0 * e0 + e1 * e1 - 0.5, e1 * e2 - e0 * e3, e1 * e3 + e0 * e2},
                          {e1 * e2 + e0 * e3, e0 * e0 + e2 * e2 - 0.5, e2 * e3 - e0 * e1},
                          {e1 * e3 - e0 * e2, e2 * e3 + e0 * e1, e0 * e0 + e3 * e3 - 0.5}};
  for (int i = 0; i < 3; ++i) w[i] = r[i] + 2 * (a[i][0] * s[0] + a[i][1] * s[1] + a[i][2] * s[2]);
}

// Largest differences, hand against generated, at a few times each solved from the start.
void check_agreement() {
  double d_pos = 0, d_rate = 0, d_acc = 0;
  for (const double rack : {0.0, 0.02, -0.03})
    for (const double t : {0.0, 0.2, 0.5, 0.77, 1.0}) {
      Model::Params params;
      params.rack = rack;
      kinegen::Solver<Model> solver(params);
      auto q = solver.initial_estimate(), qd = q, qdd = q;
      qd.setZero();
      qdd.setZero();
      Hand::State h;
      if (!solver.step(t, q, qd, qdd) || !Hand(params.travel, rack).step(t, h)) {
        std::printf("agreement check: a solve failed at t = %g, rack %g\n", t, rack);
        return;
      }
      double v[Model::num_outputs], vd[Model::num_outputs], va[Model::num_outputs], w[3];
      Model::outputs(q.data(), qd.data(), qdd.data(), t, params, v, vd, va);
      wheel_centre(q.data(), w);
      for (int i = 0; i < 3; ++i) d_pos = std::max(d_pos, std::abs(w[i] - h.w[i][0]));
      d_rate = std::max(d_rate, std::abs(vd[kWheelZ] - h.w[2][1]));
      d_acc = std::max(d_acc, std::abs(va[kWheelZ] - h.w[2][2]));
      for (int i = 0; i < 4; ++i) {
        d_pos = std::max(d_pos, std::abs(v[kToe + i] - h.angles[i][0]));
        d_rate = std::max(d_rate, std::abs(vd[kToe + i] - h.angles[i][1]));
        d_acc = std::max(d_acc, std::abs(va[kToe + i] - h.angles[i][2]));
      }
    }
  std::printf(
      "hand-written against generated at t = 0, 0.2, 0.5, 0.77, 1, rack 0, 0.02, -0.03 m (W in m;\n"
      "toe, camber, caster, kpi in rad): values %.1e, rates %.1e, accelerations %.1e (%s 1e-9)\n",
      d_pos, d_rate, d_acc, std::max({d_pos, d_rate, d_acc}) < 1e-9 ? "within" : "NOT within");
}

struct Generated {
  kinegen::Solver<Model> solver;
  kinegen::Solver<Model>::Vector q = solver.initial_estimate(), qd = q * 0, qdd = q * 0;
  double v[Model::num_outputs], vd[Model::num_outputs], va[Model::num_outputs];
  bool chunk(int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      const double t = k * kDt;
      if (!solver.step(t, q, qd, qdd)) return false;
      Model::outputs(q.data(), qd.data(), qdd.data(), t, Model::Params{}, v, vd, va);
    }
    g_checksum += v[kToe] + va[kToe];
    return true;
  }
};

// The generated step without the outputs: what the outputs cost.
struct GeneratedStepOnly {
  kinegen::Solver<Model> solver;
  kinegen::Solver<Model>::Vector q = solver.initial_estimate(), qd = q * 0, qdd = q * 0;
  bool chunk(int k0) {
    for (int k = k0; k < k0 + kChunk; ++k)
      if (!solver.step(k * kDt, q, qd, qdd)) return false;
    g_checksum += qdd[kUpright];
    return true;
  }
};

struct Dense {
  kinegen::DenseSolver<Model> solver;
  kinegen::DenseSolver<Model>::Vector q, qd, qdd;
  double v[Model::num_outputs], vd[Model::num_outputs], va[Model::num_outputs];
  explicit Dense(const kinegen::DenseSolver<Model>::Vector& start)
      : q(start), qd(start), qdd(start) {}
  bool chunk(int k0) {
    for (int k = k0; k < k0 + kChunk; ++k) {
      const double t = k * kDt;
      if (!solver.position(q, t) || !solver.velocity(q, t, qd) ||
          !solver.acceleration(q, qd, t, qdd))
        return false;
      Model::outputs(q.data(), qd.data(), qdd.data(), t, Model::Params{}, v, vd, va);
    }
    g_checksum += v[kToe] + va[kToe];
    return true;
  }
};

struct HandRun {
  Hand hand;
  Hand::State s;
  bool chunk(int k0) {
    for (int k = k0; k < k0 + kChunk; ++k)
      if (!hand.step(k * kDt, s)) return false;
    g_checksum += s.angles[0][0] + s.angles[0][2];
    return true;
  }
};

}  // namespace

int main() {
  check_agreement();
  // The dense solver starts from the generated first solve at t = 0 (its own Newton from q0
  // would start 80 mm away); the first solve is not what is timed.
  kinegen::Solver<Model> first;
  auto q = first.initial_estimate(), qd = q, qdd = q;
  if (!first.step(0.0, q, qd, qdd)) return 1;
  Generated generated;
  GeneratedStepOnly step_only;
  Dense dense(q);
  HandRun hand;
  // Interleaved: each chunk of the trajectory is timed for the three in turn.
  double t_gen = 1e300, t_step = 1e300, t_dense = 1e300, t_hand = 1e300;
  auto best = [](double& t, auto&& chunk) {
    t = std::min(t, kinegen::bench::best_ns(1, kChunk, [&](int) { return chunk(); }));
  };
  for (int c = 0; c < kChunks; ++c) {
    best(t_gen, [&] { return generated.chunk(c * kChunk); });
    best(t_step, [&] { return step_only.chunk(c * kChunk); });
    best(t_dense, [&] { return dense.chunk(c * kChunk); });
    best(t_hand, [&] { return hand.chunk(c * kChunk); });
  }
  std::printf(
      "double wishbone (nq = %d): ns per full step (position, velocity, acceleration, outputs),\n"
      "best of %d interleaved chunks of %d steps, t from 0 to 1 (+-80 mm of wheel travel)\n",
      Model::nq, kChunks, kChunk);
  std::printf("  generated step + outputs  %8.0f ns\n", t_gen);
  std::printf("  (generated step alone      %8.0f ns: the 12 outputs with rates cost the rest)\n",
              t_step);
  std::printf("  generic dense Newton      %8.0f ns  (%.1fx the generated)\n", t_dense,
              t_dense / t_gen);
  std::printf("  hand-written closure      %8.0f ns  (%.1fx the generated)\n", t_hand,
              t_hand / t_gen);
  std::printf("(checksum %g)\n", g_checksum);
  return 0;
}

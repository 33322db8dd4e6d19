// Haug's Example 3.2 (seed lecture, slider-crank): the lecture's Phi, Phi_q, nu and gamma,
// written out by hand here as an independent truth, against everything kinegen derives from
// examples/slider_crank_lecture.yaml (expression constraints) and examples/slider_crank.yaml
// (library joints): the committed generated headers and the in-process evaluator.
//
// q = [x1, y1, phi1, x2, y2, phi2] (crank, rod); crank length 1, rod length l.
#include <Eigen/Dense>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"  // format_number
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

constexpr int kSamples = 50;
// Bound on |kinegen - lecture| / (sum of |terms| of the entry). Both sides evaluate the same
// few-term sums, possibly in another order, so they differ by a few roundings at most; an
// entry whose terms are all zero must come out exactly zero.
constexpr double kRelTol = 1e-15;

struct LectureParams {
  double l = 2.0;
  double omega = 1.0;
};

// One evaluation of Phi, Phi_q (dense), nu and gamma.
struct Evaluation {
  Vec6 phi = Vec6::Zero();
  Mat6 phi_q = Mat6::Zero();
  Vec6 nu = Vec6::Zero();
  Vec6 gamma = Vec6::Zero();
};

using Evaluator = std::function<Evaluation(const Vec6& q, const Vec6& qd, double t)>;

// The lecture's matrices (value) and, per entry, the sum of the magnitudes of its terms
// (scale), which bounds the rounding error of any evaluation order.
struct Lecture {
  Evaluation value, scale;
};

Lecture lecture(const Vec6& q, const Vec6& qd, double t, const LectureParams& p) {
  const double x1 = q[0], y1 = q[1], phi1 = q[2], x2 = q[3], y2 = q[4], phi2 = q[5];
  const double w1 = qd[2], w2 = qd[5], l = p.l;
  const double c1 = std::cos(phi1), s1 = std::sin(phi1);
  const double c2 = std::cos(phi2), s2 = std::sin(phi2);
  Lecture r;
  Evaluation& v = r.value;
  Evaluation& s = r.scale;
  const auto a = [](double x) { return std::abs(x); };

  // Phi = [x1; y1; x1 - x2 + cos phi1 + l sin phi2; y1 - y2 + sin phi1 - l cos phi2; y2;
  //        phi1 - omega t]
  v.phi << x1, y1, x1 - x2 + c1 + l * s2, y1 - y2 + s1 - l * c2, y2, phi1 - p.omega * t;
  s.phi << a(x1), a(y1), a(x1) + a(x2) + a(c1) + a(l * s2), a(y1) + a(y2) + a(s1) + a(l * c2),
      a(y2), a(phi1) + a(p.omega * t);

  // Phi_q as printed in the lecture.
  // clang-format off
  v.phi_q << 1, 0, 0, 0, 0, 0,
             0, 1, 0, 0, 0, 0,
             1, 0, -s1, -1, 0, l * c2,
             0, 1, c1, 0, -1, l * s2,
             0, 0, 0, 0, 1, 0,
             0, 0, 1, 0, 0, 0;
  // clang-format on
  s.phi_q = v.phi_q.cwiseAbs();

  // nu = -Phi_t
  v.nu << 0, 0, 0, 0, 0, p.omega;
  s.nu = v.nu.cwiseAbs();

  // gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt
  const double g2a = c1 * w1 * w1, g2b = l * s2 * w2 * w2;
  const double g3a = s1 * w1 * w1, g3b = l * c2 * w2 * w2;
  v.gamma << 0, 0, g2a + g2b, g3a - g3b, 0, 0;
  s.gamma << 0, 0, a(g2a) + a(g2b), a(g3a) + a(g3b), 0, 0;
  return r;
}

// Largest |got - want| / scale over the entries (infinite if a zero-scale entry is not 0).
double worst(const Eigen::MatrixXd& got, const Eigen::MatrixXd& want,
             const Eigen::MatrixXd& scale) {
  double w = 0;
  for (Eigen::Index i = 0; i < want.size(); ++i) {
    const double diff = std::abs(got(i) - want(i));
    if (diff == 0) continue;
    w = std::max(w, scale(i) > 0 ? diff / scale(i) : std::numeric_limits<double>::infinity());
  }
  return w;
}

struct Worst {
  double phi = 0, phi_q = 0, nu = 0, gamma = 0;
};

// Compares an evaluator with the lecture at kSamples random (q, qd, t), off the constraint
// manifold too (these are identities in q, qd, t). A fixed seed keeps failures reproducible.
Worst compare_with_lecture(const Evaluator& eval, const LectureParams& p) {
  std::mt19937_64 rng(20240617);
  std::uniform_real_distribution<double> length(-5.0, 5.0), angle(-7.0, 7.0), rate(-4.0, 4.0),
      time(-10.0, 10.0);
  Worst w;
  for (int k = 0; k < kSamples; ++k) {
    Vec6 q, qd;
    q << length(rng), length(rng), angle(rng), length(rng), length(rng), angle(rng);
    for (int i = 0; i < 6; ++i) qd[i] = rate(rng);
    const double t = time(rng);
    const Lecture ref = lecture(q, qd, t, p);
    const Evaluation got = eval(q, qd, t);
    w.phi = std::max(w.phi, worst(got.phi, ref.value.phi, ref.scale.phi));
    w.phi_q = std::max(w.phi_q, worst(got.phi_q, ref.value.phi_q, ref.scale.phi_q));
    w.nu = std::max(w.nu, worst(got.nu, ref.value.nu, ref.scale.nu));
    w.gamma = std::max(w.gamma, worst(got.gamma, ref.value.gamma, ref.scale.gamma));
  }
  return w;
}

void check_worst(const Worst& w) {
  INFO("worst relative error: phi " << w.phi << ", phi_q " << w.phi_q << ", nu " << w.nu
                                    << ", gamma " << w.gamma);
  CHECK(w.phi <= kRelTol);
  CHECK(w.phi_q <= kRelTol);
  CHECK(w.nu <= kRelTol);
  CHECK(w.gamma <= kRelTol);
}

// The lecture's structural non-zeros of Phi_q: 12 of them.
std::set<std::pair<int, int>> lecture_pattern() {
  return {{0, 0}, {1, 1},                  // x1, y1
          {2, 0}, {2, 2}, {2, 3}, {2, 5},  // x row of the crank-rod pin
          {3, 1}, {3, 2}, {3, 4}, {3, 5},  // y row of the crank-rod pin
          {4, 4},                          // y2
          {5, 2}};                         // driver on phi1
}

template <class Rows, class Cols>
void check_pattern(const Rows& rows, const Cols& cols) {
  REQUIRE(rows.size() == cols.size());
  std::set<std::pair<int, int>> pattern;
  for (std::size_t k = 0; k < rows.size(); ++k) pattern.insert({rows[k], cols[k]});
  // No duplicate entries (a scatter would silently overwrite one), nothing outside the lecture's
  // non-zeros, and none of them missing.
  CHECK(pattern.size() == rows.size());
  CHECK(rows.size() == 12);
  CHECK(pattern == lecture_pattern());
}

template <class Model>
Evaluator generated_evaluator(const LectureParams& lp) {
  typename Model::Params p;
  p.l = lp.l;
  p.omega = lp.omega;
  return [p](const Vec6& q, const Vec6& qd, double t) {
    Evaluation e;
    Model::phi(q.data(), t, p, e.phi.data());
    std::array<double, Model::jac_nnz> values;
    Model::phi_q(q.data(), t, p, values.data());
    for (int k = 0; k < Model::jac_nnz; ++k)
      e.phi_q(Model::jac_rows[k], Model::jac_cols[k]) = values[k];
    Model::nu(q.data(), t, p, e.nu.data());
    Model::gamma(q.data(), qd.data(), t, p, e.gamma.data());
    return e;
  };
}

std::string example(const std::string& file) {
  return std::string(KINEGEN_SOURCE_DIR) + "/examples/" + file;
}

std::unique_ptr<kinegen::codegen::CompiledModel> compile(const std::string& file,
                                                         const LectureParams* p) {
  std::vector<kinegen::codegen::ParamOverride> overrides;
  if (p) {
    overrides.push_back({"l", kinegen::codegen::format_number(p->l)});
    overrides.push_back({"omega", kinegen::codegen::format_number(p->omega)});
  }
  return kinegen::codegen::CompiledModel::from_file(example(file), overrides);
}

// The evaluator keeps a pointer to the model, which must outlive it.
Evaluator in_process_evaluator(const kinegen::codegen::CompiledModel& model) {
  auto ev = std::make_shared<kinegen::codegen::ModelEvaluator<double>>(model);
  return [ev](const Vec6& q, const Vec6& qd, double t) {
    Evaluation e;
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(6, 6);
    ev->phi(q.data(), t, e.phi.data());
    ev->jacobian(q.data(), t, jac);
    e.phi_q = jac;
    ev->nu(q.data(), t, e.nu.data());
    ev->gamma(q.data(), qd.data(), t, e.gamma.data());
    return e;
  };
}

const LectureParams kOtherParams{2.7, -1.3};

}  // namespace

TEMPLATE_TEST_CASE("generated header reproduces Haug Example 3.2", "[seed]",
                   kinegen::models::slider_crank_lecture, kinegen::models::slider_crank) {
  STATIC_REQUIRE(TestType::nq == 6);
  STATIC_REQUIRE(TestType::nc == 6);
  check_pattern(TestType::jac_rows, TestType::jac_cols);

  SECTION("default parameters (l = 2, omega = 1)") {
    check_worst(compare_with_lecture(generated_evaluator<TestType>({}), {}));
  }
  SECTION("l = 2.7, omega = -1.3") {
    check_worst(compare_with_lecture(generated_evaluator<TestType>(kOtherParams), kOtherParams));
  }
}

TEST_CASE("in-process evaluator reproduces Haug Example 3.2", "[seed]") {
  const std::string file =
      GENERATE(std::string("slider_crank_lecture.yaml"), std::string("slider_crank.yaml"));
  INFO("examples/" << file);
  const bool other = GENERATE(false, true);
  const LectureParams params = other ? kOtherParams : LectureParams{};
  INFO("l = " << params.l << ", omega = " << params.omega);

  const auto model = compile(file, other ? &params : nullptr);
  REQUIRE(model->nq() == 6);
  REQUIRE(model->nc() == 6);
  check_pattern(model->programs().jac_rows, model->programs().jac_cols);
  check_worst(compare_with_lecture(in_process_evaluator(*model), params));
}

// The tolerance must be able to fail: a single wrong term is far outside it.
TEST_CASE("Example 3.2 comparison detects a perturbed term", "[seed]") {
  const Evaluator good = generated_evaluator<kinegen::models::slider_crank_lecture>({});
  const Evaluator off_by_ulps = [&good](const Vec6& q, const Vec6& qd, double t) {
    Evaluation e = good(q, qd, t);
    e.gamma[3] *= 1 + 64 * std::numeric_limits<double>::epsilon();
    return e;
  };
  CHECK(compare_with_lecture(off_by_ulps, {}).gamma > kRelTol);
  // Parameters that differ from the lecture's (l and omega exchanged) show up.
  const Evaluator swapped = generated_evaluator<kinegen::models::slider_crank_lecture>({1.0, 2.0});
  CHECK(compare_with_lecture(swapped, {}).nu > kRelTol);
}

// The generated functions against their own source, numerically:
// - Phi_q and nu against complex-step derivatives of the generated phi (exact to rounding),
//   and gamma against the complex-step derivative of d(Phi)/dt = Phi_q qd - nu along the
//   motion, for T = double, float and std::complex<double>;
// - the in-process evaluator against the generated double code, bit for bit (both follow the
//   same straight-line program, so the command line and embedded code agree exactly).
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <random>
#include <string>
#include <type_traits>

#include "four_bar.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "offset_slider_crank.hpp"
#include "quick_return.hpp"
#include "slider_crank.hpp"
#include "slider_crank_lecture.hpp"

namespace {

using Complex = std::complex<double>;
using kinegen::codegen::CompiledModel;
using kinegen::codegen::ModelEvaluator;

template <class T>
struct Traits {
  static double real(const T& v) { return static_cast<double>(v); }
  static double imag(const T&) { return 0; }
  static constexpr double kRelTol = 1e-13;
};
template <>
struct Traits<float> {
  static double real(float v) { return v; }
  static double imag(float) { return 0; }
  static constexpr double kRelTol = 2e-5;  // a few float ulps of the block's scale
};
template <>
struct Traits<Complex> {
  static double real(const Complex& v) { return v.real(); }
  static double imag(const Complex& v) { return v.imag(); }
  static constexpr double kRelTol = 1e-13;
};

constexpr double kStep = 1e-30;  // complex step: no subtractive cancellation at any size

// Dense Phi_q of a generated model, in scalar U.
template <class Model, class U>
Eigen::Matrix<U, Model::nc, Model::nq> dense_jacobian(const U* q, U t,
                                                      const typename Model::Params& p) {
  U values[Model::jac_nnz];
  Model::phi_q(q, t, p, values);
  Eigen::Matrix<U, Model::nc, Model::nq> jac = Eigen::Matrix<U, Model::nc, Model::nq>::Zero();
  for (int k = 0; k < Model::jac_nnz; ++k) jac(Model::jac_rows[k], Model::jac_cols[k]) = values[k];
  return jac;
}

template <class Model, class T>
void check_model(const char* name) {
  INFO("model " << name);
  constexpr int nq = Model::nq, nc = Model::nc;
  const typename Model::Params p{};
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double err_jac = 0, err_nu = 0, err_gamma = 0, imag = 0;
  double scale_jac = 1, scale_nu = 1, scale_gamma = 1;

  for (int sample = 0; sample < 20; ++sample) {
    double q[nq], qd[nq];
    for (int k = 0; k < nq; ++k) {
      q[k] = Model::q0[k] + 0.3 * unit(rng);
      qd[k] = unit(rng);
    }
    const double t = unit(rng);
    // Round the sample to T's precision first, so the comparison measures the generated
    // arithmetic in T, not the rounding of its inputs.
    T qt[nq], qdt[nq];
    for (int k = 0; k < nq; ++k) {
      qt[k] = T(q[k]);
      qdt[k] = T(qd[k]);
      q[k] = Traits<T>::real(qt[k]);
      qd[k] = Traits<T>::real(qdt[k]);
    }
    const double tr = Traits<T>::real(T(t));

    // The function under test, in T.
    T jac_values[Model::jac_nnz], nu[nc], gamma[nc];
    Model::phi_q(qt, T(tr), p, jac_values);
    Model::nu(qt, T(tr), p, nu);
    Model::gamma(qt, qdt, T(tr), p, gamma);
    Eigen::Matrix<double, nc, nq> jac = Eigen::Matrix<double, nc, nq>::Zero();
    for (int k = 0; k < Model::jac_nnz; ++k) {
      jac(Model::jac_rows[k], Model::jac_cols[k]) = Traits<T>::real(jac_values[k]);
      imag = std::max(imag, std::abs(Traits<T>::imag(jac_values[k])));
    }

    // References by complex step on the generated complex functions.
    Complex qc[nq], out[nc];
    for (int k = 0; k < nq; ++k) {
      for (int m = 0; m < nq; ++m) qc[m] = q[m];
      qc[k] += Complex(0, kStep);
      Model::phi(qc, Complex(tr), p, out);
      for (int r = 0; r < nc; ++r) {
        const double ref = out[r].imag() / kStep;
        err_jac = std::max(err_jac, std::abs(jac(r, k) - ref));
        scale_jac = std::max(scale_jac, std::abs(ref));
      }
    }
    for (int m = 0; m < nq; ++m) qc[m] = q[m];
    Model::phi(qc, Complex(tr, kStep), p, out);
    for (int r = 0; r < nc; ++r) {
      const double ref = -out[r].imag() / kStep;
      err_nu = std::max(err_nu, std::abs(Traits<T>::real(nu[r]) - ref));
      scale_nu = std::max(scale_nu, std::abs(ref));
    }
    // gamma = -d/ds [Phi_q qd - nu] at (q + s qd, t + s), s = 0.
    for (int m = 0; m < nq; ++m) qc[m] = Complex(q[m], kStep * qd[m]);
    const Complex tc(tr, kStep);
    const auto jc = dense_jacobian<Model, Complex>(qc, tc, p);
    Complex nuc[nc];
    Model::nu(qc, tc, p, nuc);
    Eigen::Matrix<Complex, nq, 1> qdc;
    for (int m = 0; m < nq; ++m) qdc[m] = qd[m];
    const Eigen::Matrix<Complex, nc, 1> dphi = jc * qdc;
    for (int r = 0; r < nc; ++r) {
      const double ref = -(dphi[r] - nuc[r]).imag() / kStep;
      err_gamma = std::max(err_gamma, std::abs(Traits<T>::real(gamma[r]) - ref));
      scale_gamma = std::max(scale_gamma, std::abs(ref));
    }
  }
  INFO("errors: phi_q " << err_jac << ", nu " << err_nu << ", gamma " << err_gamma);
  CHECK(err_jac <= Traits<T>::kRelTol * scale_jac);
  CHECK(err_nu <= Traits<T>::kRelTol * scale_nu);
  CHECK(err_gamma <= Traits<T>::kRelTol * scale_gamma);
  CHECK(imag == 0);  // real inputs give real outputs
}

template <class Model>
void check_evaluator_matches(const char* file) {
  INFO("mechanism " << file);
  const auto model = CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) + "/examples/" + file);
  REQUIRE(model->nq() == Model::nq);
  REQUIRE(model->nc() == Model::nc);
  REQUIRE(static_cast<int>(model->programs().jac_rows.size()) == Model::jac_nnz);
  ModelEvaluator<double> eval(*model);
  const typename Model::Params p{};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-2.0, 2.0);
  int mismatches = 0;
  for (int sample = 0; sample < 50; ++sample) {
    double q[Model::nq], qd[Model::nq];
    for (int k = 0; k < Model::nq; ++k) {
      q[k] = Model::q0[k] + unit(rng);
      qd[k] = unit(rng);
    }
    const double t = unit(rng);
    double a[Model::nc + Model::jac_nnz], b[Model::nc + Model::jac_nnz];
    const auto compare = [&](int n) {
      for (int k = 0; k < n; ++k) mismatches += !(a[k] == b[k]);
    };
    Model::phi(q, t, p, a);
    eval.phi(q, t, b);
    compare(Model::nc);
    Model::phi_q(q, t, p, a);
    eval.phi_q_values(q, t, b);
    compare(Model::jac_nnz);
    Model::nu(q, t, p, a);
    eval.nu(q, t, b);
    compare(Model::nc);
    Model::gamma(q, qd, t, p, a);
    eval.gamma(q, qd, t, b);
    compare(Model::nc);
  }
  CHECK(mismatches == 0);
}

template <class T>
void check_all_models() {
  check_model<kinegen::models::slider_crank_lecture, T>("slider_crank_lecture");
  check_model<kinegen::models::slider_crank, T>("slider_crank");
  check_model<kinegen::models::offset_slider_crank, T>("offset_slider_crank");
  check_model<kinegen::models::four_bar, T>("four_bar");
  check_model<kinegen::models::quick_return, T>("quick_return");
}

}  // namespace

TEMPLATE_TEST_CASE("generated Phi_q, nu and gamma match complex-step derivatives",
                   "[generated][derivatives]", double, float, Complex) {
  check_all_models<TestType>();
}

TEST_CASE("the in-process evaluator and the generated code agree bit for bit",
          "[generated][evaluator]") {
  check_evaluator_matches<kinegen::models::slider_crank_lecture>("slider_crank_lecture.yaml");
  check_evaluator_matches<kinegen::models::slider_crank>("slider_crank.yaml");
  check_evaluator_matches<kinegen::models::offset_slider_crank>("offset_slider_crank.yaml");
  check_evaluator_matches<kinegen::models::four_bar>("four_bar.yaml");
  check_evaluator_matches<kinegen::models::quick_return>("quick_return.yaml");
}

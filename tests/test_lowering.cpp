// The lowering's sign convention must not depend on which sign GiNaC gave a sum: GiNaC picks
// it by hash order, which changes between processes (test_determinism sees the headers; this
// builds both signs in one process, held so that GiNaC cannot undo them).
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/program/program.hpp"

namespace {

namespace cg = kinegen::codegen;
using GiNaC::ex;

const std::string kSliderCrank =
    std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/slider_crank_outputs.yaml";

int count_squares(const cg::Program& p) {
  int n = 0;
  for (const auto& node : p.nodes) n += node.kind == cg::OpKind::kPowInt && node.exponent == 2;
  return n;
}

}  // namespace

TEST_CASE("a square of a sum is one node whichever sign GiNaC holds its base with",
          "[lowering][determinism]") {
  const auto model = cg::CompiledModel::from_file(kSliderCrank);
  const auto& s = model->symbols();
  const ex u = s.q(0) - s.q(1);  // leading term q0, positive
  const ex up = GiNaC::power(u, 2).hold(), down = GiNaC::power(-u, 2).hold();
  const std::vector<double> q = {0.3, 1.7, 0.4, 2.0, 0.5, 0.6};
  const double u2 = (q[0] - q[1]) * (q[0] - q[1]);
  for (const auto& [a, b] : {std::pair{up, up}, std::pair{down, down}, std::pair{up, down}}) {
    INFO(a << " and " << b);
    const cg::Program p = cg::lower({a * s.q(2), b * sin(s.q(2))}, s);
    CHECK(count_squares(p) == 1);  // shared, so computed once into a named term
    cg::ProgramEvaluator<double> eval(p);
    double out[2];
    eval.run(q.data(), nullptr, 0.0, model->params().data(), out);
    CHECK(out[0] == Approx(u2 * q[2]).epsilon(1e-15));
    CHECK(out[1] == Approx(u2 * std::sin(q[2])).epsilon(1e-15));
  }
}

namespace {

// The nodes in order, by what they compute: two programs that compute alike print alike.
std::string shape(const cg::Program& p) {
  std::string s;
  for (const auto& n : p.nodes) {
    s += std::to_string(static_cast<int>(n.kind)) + "/" + std::to_string(n.exponent) + "/" +
         std::to_string(n.value) + "/" + std::to_string(static_cast<int>(n.input.kind)) +
         std::to_string(n.input.index) + "(";
    for (int a : n.args) s += std::to_string(a) + ",";
    s += ") ";
  }
  return s;
}

}  // namespace

TEST_CASE("a sum's term -1/u sorts alike whether GiNaC holds it as (-u)^-1 or as -(u^-1)",
          "[lowering][determinism]") {
  // GiNaC holds an odd power of a sum with the sign its hash order picks: the term is the power
  // (-u)^-1 in one process and the product -1 * u^-1 in another (the suspension's output
  // rates in examples/spatial/double_wishbone.yaml). The sum's order must not follow.
  const auto model = cg::CompiledModel::from_file(kSliderCrank);
  const auto& s = model->symbols();
  const ex u = s.q(0) - s.q(1);  // leading term q0, positive
  const ex as_power = GiNaC::power(-u, -1).hold();
  const ex as_product = -GiNaC::power(u, -1);
  REQUIRE(GiNaC::is_a<GiNaC::power>(as_power));
  REQUIRE(GiNaC::is_a<GiNaC::mul>(as_product));
  const ex rest = 2 * s.q(2) * s.q(3) + s.q(4);
  const cg::Program a = cg::lower({rest + as_power}, s), b = cg::lower({rest + as_product}, s);
  CHECK(shape(a) == shape(b));
  const std::vector<double> q = {0.3, 1.7, 0.4, 2.0, 0.5, 0.6};
  double out_a = 0, out_b = 0;
  cg::ProgramEvaluator<double>(a).run(q.data(), nullptr, 0.0, model->params().data(), &out_a);
  cg::ProgramEvaluator<double>(b).run(q.data(), nullptr, 0.0, model->params().data(), &out_b);
  CHECK(out_a == out_b);
  CHECK(out_a == Approx(2 * 0.4 * 2.0 + 0.5 - 1 / (0.3 - 1.7)).epsilon(1e-15));
}

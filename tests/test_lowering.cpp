// The lowering's sign convention must not depend on which sign GiNaC gave a sum: GiNaC picks
// it by hash order, which changes between processes (test_determinism sees the headers; this
// builds both signs in one process, held so that GiNaC cannot undo them).
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/program/canonical_key.hpp"
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

TEST_CASE("a sum's term -1/u has one key whether GiNaC holds it as (-u)^-1 or as -1 * u^-1",
          "[lowering][determinism]") {
  // GiNaC evaluates -1 * u^-1 to either form by hash order (so the term of a sum reads back as
  // one form in one process and as the other in another: the suspension's output rates in
  // examples/spatial/double_wishbone.yaml). A sum is ordered by its terms' keys, which must
  // not differ between the two. Both forms are built held, so that GiNaC cannot pick.
  const auto model = cg::CompiledModel::from_file(kSliderCrank);
  const auto& s = model->symbols();
  const ex u = s.q(0) - s.q(1);  // leading term q0, positive
  const ex as_power = GiNaC::power(-u, -1).hold();
  const ex as_product = GiNaC::mul(ex(-1), GiNaC::power(u, -1)).hold();
  REQUIRE(GiNaC::is_a<GiNaC::power>(as_power));
  REQUIRE(GiNaC::is_a<GiNaC::mul>(as_product));
  cg::CanonicalKey keys(s);
  CHECK(keys.key(as_power) == keys.key(as_product));
  // And each lowers to the same value, -1 / (q0 - q1).
  const std::vector<double> q = {0.3, 1.7, 0.4, 2.0, 0.5, 0.6};
  for (const ex& e : {as_power, as_product}) {
    double out = 0;
    cg::ProgramEvaluator<double>(cg::lower({e}, s))
        .run(q.data(), nullptr, 0.0, model->params().data(), &out);
    CHECK(out == Approx(-1 / (0.3 - 1.7)).epsilon(1e-15));
  }
}

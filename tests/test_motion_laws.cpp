// Motion laws and table splines, the kernels on their own: the laws against their
// formulas, each derivative against the complex step of the one below it, the not-a-knot
// spline against a cubic it must reproduce, the periodic spline against a smooth
// periodic law, and the table reader against hostile files.
#include <catch2/catch.hpp>

#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <functional>

#include "kinegen/codegen/model/table.hpp"
#include "kinegen/kernels/motion_law.hpp"
#include "kinegen/kernels/spline.hpp"

namespace {

using kinegen::kernels::motion_law;
using Complex = std::complex<double>;
constexpr double kPi = 3.14159265358979323846;

// The laws as the spec writes them, on [0, 1].
double formula(int law, double x) {
  switch (law) {
    case kinegen::kernels::kCycloidal: return x - std::sin(2 * kPi * x) / (2 * kPi);
    case kinegen::kernels::kHarmonic: return (1 - std::cos(kPi * x)) / 2;
    case kinegen::kernels::kPoly345: return 10 * std::pow(x, 3) - 15 * std::pow(x, 4) + 6 * std::pow(x, 5);
    default:
      return 35 * std::pow(x, 4) - 84 * std::pow(x, 5) + 70 * std::pow(x, 6) - 20 * std::pow(x, 7);
  }
}

}  // namespace

TEST_CASE("motion laws match their formulas on [0, 1) and clamp outside it", "[laws]") {
  for (int law = 0; law < 4; ++law) {
    CAPTURE(law);
    for (int k = 0; k <= 1000; ++k) {
      const double x = k / 1000.0;
      CHECK(motion_law(law, 0, x) == Approx(formula(law, x)).margin(1e-15));
    }
    for (double x : {-1e9, -1.0, -1e-300}) {
      for (int order = 0; order <= 4; ++order) CHECK(motion_law(law, order, x) == 0.0);
    }
    // At 0 the formula (as amended in version 3: the limit from the right), whose value and
    // first derivative are 0 for every law (tests/test_law_boundaries.cpp: the higher ones).
    CHECK(motion_law(law, 0, 0.0) == 0.0);
    CHECK(motion_law(law, 1, 0.0) == 0.0);
    for (double x : {1.0, 1.0 + 1e-15, 2.0, 1e9}) {
      CHECK(motion_law(law, 0, x) == 1.0);
      for (int order = 1; order <= 4; ++order) CHECK(motion_law(law, order, x) == 0.0);
    }
    CHECK(std::isnan(motion_law(law, 0, std::nan(""))));
    CHECK(std::isnan(motion_law(law, 2, std::nan(""))));
  }
}

TEST_CASE("each motion-law derivative is the complex step of the one below", "[laws]") {
  const double h = 1e-30;
  for (int law = 0; law < 4; ++law) {
    for (int order = 1; order <= 5; ++order) {
      CAPTURE(law, order);
      double worst = 0, largest = 0;
      for (int k = 1; k < 400; ++k) {
        const double x = k / 400.0;
        const double cs = std::imag(motion_law(law, order - 1, Complex(x, h))) / h;
        const double exact = motion_law(law, order, x);
        worst = std::max(worst, std::abs(cs - exact));
        largest = std::max(largest, std::abs(exact));
      }
      CAPTURE(worst, largest);
      // Horner on the polynomials' alternating coefficients cancels about 2 digits.
      CHECK(worst <= 2e-13 * std::max(1.0, largest));
    }
  }
}

TEST_CASE("motion laws: rest at the ends where the law promises it", "[laws]") {
  // Cycloidal, 3-4-5 and 4-5-6-7 start and end with zero velocity and acceleration (4-5-6-7
  // zero jerk too); harmonic has zero velocity but a jump in acceleration.
  const double e = 1e-7;
  using namespace kinegen::kernels;
  for (int law : {kCycloidal, kPoly345, kPoly4567}) {
    for (int order = 1; order <= 2; ++order) {
      CHECK(std::abs(motion_law(law, order, e)) < 1e-5);
      CHECK(std::abs(motion_law(law, order, 1 - e)) < 1e-5);
    }
  }
  CHECK(std::abs(motion_law(kPoly4567, 3, 1e-9)) < 1e-5);  // jerk 840 x near 0
  CHECK(motion_law(kHarmonic, 2, e) == Approx(kPi * kPi / 2).epsilon(1e-10));
  // Midpoints by symmetry: f(1/2) = 1/2 for every law.
  for (int law = 0; law < 4; ++law) CHECK(motion_law(law, 0, 0.5) == Approx(0.5).epsilon(1e-15));
}

TEST_CASE("motion laws in float compute in float", "[laws]") {
  for (int law = 0; law < 4; ++law)
    for (int k = 0; k <= 100; ++k) {
      const float x = k / 100.0f;
      const float v = motion_law(law, 1, x);
      CHECK(v == Approx(motion_law(law, 1, double(x))).epsilon(32 * 1.2e-7).margin(1e-6));
    }
}

TEST_CASE("the not-a-knot spline reproduces a cubic to rounding", "[tables]") {
  const auto cubic = [](double x) { return 0.7 - 1.3 * x + 0.25 * x * x - 0.04 * x * x * x; };
  const auto d1 = [](double x) { return -1.3 + 0.5 * x - 0.12 * x * x; };
  const auto d2 = [](double x) { return 0.5 - 0.24 * x; };
  for (int n : {4, 5, 9, 40}) {
    std::vector<double> t, y;
    for (int i = 0; i < n; ++i) {
      const double ti = -2 + 7.0 * i / (n - 1) + (i % 3 == 1 ? 0.31 / n : 0.0);  // irregular
      t.push_back(ti);
      y.push_back(cubic(ti));
    }
    const auto s = kinegen::codegen::fit_not_a_knot(t, y);
    for (int k = 0; k <= 700; ++k) {
      const double x = t.front() + (t.back() - t.front()) * k / 700.0;
      double f[3];
      REQUIRE(s.eval(x, f));
      CAPTURE(n, x);
      CHECK(f[0] == Approx(cubic(x)).margin(1e-13));
      CHECK(f[1] == Approx(d1(x)).margin(1e-12));
      CHECK(f[2] == Approx(d2(x)).margin(1e-11));
    }
    double f[3];
    CHECK(s.eval(t.back(), f));
    CHECK_FALSE(s.eval(t.back() + 1e-9, f));  // never extrapolated
    CHECK_FALSE(s.eval(t.front() - 1e-9, f));
    CHECK_FALSE(s.eval(std::nan(""), f));
  }
}

TEST_CASE("spline derivatives are the complex step of its value", "[tables]") {
  std::vector<double> t, y;
  for (int i = 0; i < 12; ++i) {
    t.push_back(i * 0.5);
    y.push_back(std::exp(-0.3 * i) * std::sin(i));
  }
  const auto s = kinegen::codegen::fit_not_a_knot(t, y);
  for (int k = 1; k < 100; ++k) {
    const double x = 5.5 * k / 100.0;
    Complex fc[3];
    double f[3];
    REQUIRE(kinegen::kernels::spline_eval(s.t.data(), s.y.data(), s.m.data(), 12,
                                          Complex(x, 1e-30), fc));
    REQUIRE(s.eval(x, f));
    CHECK(std::imag(fc[0]) / 1e-30 == Approx(f[1]).margin(1e-13));
    CHECK(std::imag(fc[1]) / 1e-30 == Approx(f[2]).margin(1e-12));
    CHECK(std::real(fc[0]) == f[0]);
  }
}

TEST_CASE("the periodic spline repeats with its rise and is smooth across the seam", "[tables]") {
  const double period = 2.0, rise = 2 * kPi;
  const auto law = [&](double x) {
    return rise * x / period + 0.4 * std::sin(2 * kPi * x / period) +
           0.1 * std::cos(4 * kPi * x / period);
  };
  std::vector<double> t, y;
  const int n = 65;
  for (int i = 0; i < n; ++i) {
    t.push_back(period * i / (n - 1));
    y.push_back(law(t.back()));
  }
  const auto s = kinegen::codegen::fit_periodic(t, y);
  double worst = 0;
  for (int k = -300; k <= 900; ++k) {
    const double x = 3.0 * k / 300.0 + 0.0137;
    double f[3];
    REQUIRE(s.eval(x, f));
    worst = std::max(worst, std::abs(f[0] - law(x)));
  }
  CHECK(worst < 2e-6);  // h^4 accuracy: h = 1/32, the law's 4th derivative is about 60
  double a[3], b[3];
  const double dx = 1e-9;
  for (int turn : {1, 2, -1}) {
    REQUIRE(s.eval(turn * period - dx, a));
    REQUIRE(s.eval(turn * period + dx, b));
    CHECK(b[0] - a[0] == Approx(a[1] * 2 * dx).margin(1e-12));  // f continuous
    CHECK(b[1] == Approx(a[1]).margin(1e-6));                       // f' continuous
    CHECK(b[2] == Approx(a[2]).margin(1e-6));                       // f'' continuous
  }
  double f0[3], f3[3];
  REQUIRE(s.eval(0.3, f0));
  REQUIRE(s.eval(0.3 + 3 * period, f3));
  CHECK(f3[0] - f0[0] == Approx(3 * rise).epsilon(1e-14));
}

namespace {
namespace fs = std::filesystem;

struct TableDir {
  fs::path dir;
  TableDir() {
    dir = fs::path(KINEGEN_TEST_TMP) / "tables";
    fs::remove_all(dir);
    fs::create_directories(dir / "mech");
  }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(dir / name) << text;
    return name;
  }
  std::string mechanism() const { return (dir / "mech" / "m.yaml").string(); }
};

std::string read_error(const std::string& mech, const std::string& path) {
  kinegen::codegen::TableSource src{mech, "drivers[0] table", {7, 5}};
  std::vector<double> t, v;
  try {
    kinegen::codegen::read_table(path, src, t, v);
  } catch (const kinegen::codegen::InputError& e) {
    CHECK(e.loc().line == 7);
    CHECK(e.item() == "drivers[0] table");
    return e.detail();
  }
  return "no error";
}
}  // namespace

TEST_CASE("hostile tables are refused with the reason", "[tables]") {
  TableDir d;
  const std::string mech = d.mechanism();
  const auto put = [&](const std::string& name, const std::string& text) {
    std::ofstream(d.dir / "mech" / name) << text;
    return name;
  };
  CHECK_THAT(read_error(mech, "none.csv"), Catch::Contains("does not exist"));
  CHECK_THAT(read_error(mech, put("empty.csv", "")), Catch::Contains("empty"));
  CHECK_THAT(read_error(mech, put("header.csv", "t,value\n")), Catch::Contains("at least 4"));
  CHECK_THAT(read_error(mech, put("short.csv", "t,v\n0,1\n1,2\n2,3\n")),
             Catch::Contains("at least 4"));
  CHECK_THAT(read_error(mech, put("text.csv", "t,v\n0,1\n1,abc\n2,3\n3,4\n")),
             Catch::Contains("line 3 is not two numbers"));
  CHECK_THAT(read_error(mech, put("down.csv", "t,v\n0,1\n1,2\n1,3\n3,4\n")),
             Catch::Contains("increase strictly"));
  CHECK_THAT(read_error(mech, put("nan.csv", "t,v\n0,1\n1,nan\n2,3\n3,4\n")),
             Catch::Contains("not finite"));
  CHECK_THAT(read_error(mech, put("three.csv", "t,v,w\n0,1,2\n")),
             Catch::Contains("two columns"));
  CHECK_THAT(read_error(mech, put("noheader.csv", "0,1\n1,2\n2,3\n3,4\n")),
             Catch::Contains("header row"));
  // Leaving the mechanism's folder: by .., by an absolute path, by a link.
  d.write("outside.csv", "t,v\n0,1\n1,2\n2,3\n3,4\n");
  CHECK_THAT(read_error(mech, "../outside.csv"), Catch::Contains("outside the mechanism's folder"));
  CHECK_THAT(read_error(mech, (d.dir / "outside.csv").string()),
             Catch::Contains("outside the mechanism's folder"));
  fs::create_symlink(d.dir / "outside.csv", d.dir / "mech" / "link.csv");
  CHECK_THAT(read_error(mech, "link.csv"), Catch::Contains("outside the mechanism's folder"));
  fs::create_directories(d.dir / "mech" / "data");
  put("data/ok.csv", "time,angle\r\n0,1\r\n\r\n1,2\r\n2,3\r\n3,4.5\r\n");
  CHECK(read_error(mech, "data/ok.csv") == "no error");
  std::vector<double> t, v;
  kinegen::codegen::read_table("data/ok.csv", {mech, "x", {}}, t, v);
  CHECK(t == std::vector<double>{0, 1, 2, 3});
  CHECK(v == std::vector<double>{1, 2, 3, 4.5});
}

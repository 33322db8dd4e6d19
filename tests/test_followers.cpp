// Extra coordinates and curve joints (`coordinates:`, point_follower and cam_follower)
// against closed forms:
// - an eccentric circular cam (e, R, omega) under a flat-faced translating follower:
//   y = R + e sin(theta), the contact at a = pi/2 - theta on the cam, b = e cos(theta) on the face;
// - the same cam under a roller follower: y = e sin(theta) + sqrt((R + r)^2 - e^2 cos^2(theta));
// - a pin in a parabolic slot y = k u^2 on a plate turned by alpha, carried by a crosshead along
//   x = X(t): u is the root of k sin(alpha) u^2 - cos(alpha) u + X = 0;
// velocities and accelerations against the closed forms' derivatives; `kinegen check` with its
// three methods; the generated headers against analyze; the cam's normal force J.fn
// against the spring and the follower's inertia, positive, and negative where the spring is too
// weak; hostile input for the new keys.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cam_flat.hpp"
#include "cam_roller.hpp"
#include "disc_cam.hpp"
#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "parabolic_slot.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace {

namespace kc = kinegen::codegen;
namespace km = kinegen::models;
namespace fs = std::filesystem;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kPi = 3.14159265358979323846;

std::string mechanism(const std::string& name) {
  return std::string(KINEGEN_SOURCE_DIR) + "/tests/mechanisms/" + name + ".yaml";
}

std::vector<kc::StateRow> analyze(const kc::CompiledModel& model, const kc::TimeGrid& grid) {
  std::vector<kc::StateRow> rows;
  kc::run_analysis(model, grid, [&](const kc::StateRow& r) { rows.push_back(r); });
  return rows;
}

// The largest |value - truth| / (1 + |truth|) of each block.
struct Error {
  double q = 0, qd = 0, qdd = 0;
  static void add(double& block, double value, double truth) {
    block = std::max(block, std::abs(value - truth) / (1 + std::abs(truth)));
  }
};

int column(const std::vector<std::string>& names, const std::string& name) {
  const auto it = std::find(names.begin(), names.end(), name);
  REQUIRE(it != names.end());
  return static_cast<int>(it - names.begin());
}

// The generated header's solve_step against analyze over the same grid, relative.
template <class M>
double generated_against_analyze(const std::vector<kc::StateRow>& rows) {
  typename M::Params p{};
  double q[M::nq], qd[M::nq] = {}, qdd[M::nq] = {};
  for (int k = 0; k < M::nq; ++k) q[k] = M::q0[k];
  double worst = 0;
  for (const auto& r : rows) {
    const auto report = M::solve_step(q, r.t, p, qd, qdd, typename M::BlockOptions{});
    REQUIRE(report.status == 0);
    for (int c = 0; c < M::nq; ++c) {
      worst = std::max(worst, std::abs(q[c] - r.q[c]) / (1 + std::abs(r.q[c])));
      worst = std::max(worst, std::abs(qd[c] - r.qd[c]) / (1 + std::abs(r.qd[c])));
      worst = std::max(worst, std::abs(qdd[c] - r.qdd[c]) / (1 + std::abs(r.qdd[c])));
    }
  }
  return worst;
}

// cam_roller.yaml's lift and its derivatives in theta: y = e sin + S, S = sqrt(D),
// D = (R + r)^2 - e^2 cos^2.
struct RollerLift {
  double y, dy, ddy;
};
RollerLift roller_lift(double e, double rr, double th) {
  const double s = std::sin(th), c = std::cos(th);
  const double S = std::sqrt(rr * rr - e * e * c * c), w = e * e * s * c;
  return {e * s + S, e * c + w / S, -e * s + e * e * std::cos(2 * th) / S - w * w / (S * S * S)};
}

}  // namespace

TEST_CASE("followers: an eccentric cam under a flat-faced follower", "[followers]") {
  // cam_flat.yaml: e 0.02, R 0.05, omega 2; q = cam (0-2), follower (3-5), a (6), b (7).
  const double e = 0.02, R = 0.05, w = 2;
  const auto model = kc::CompiledModel::from_file(mechanism("cam_flat"));
  REQUIRE(model->nq() == 8);
  const auto rows = analyze(*model, {0, 2 * kPi, 720});  // two cam turns
  REQUIRE(rows.size() == 721);
  Error err;
  for (const auto& r : rows) {
    const double th = w * r.t, s = std::sin(th), c = std::cos(th);
    Error::add(err.q, r.q[4], R + e * s);
    Error::add(err.qd, r.qd[4], e * w * c);
    Error::add(err.qdd, r.qdd[4], -e * w * w * s);
    Error::add(err.q, r.q[6], kPi / 2 - th);  // continuous, never wrapped
    Error::add(err.qd, r.qd[6], -w);
    Error::add(err.qdd, r.qdd[6], 0);
    Error::add(err.q, r.q[7], e * c);
    Error::add(err.qd, r.qd[7], -e * w * s);
    Error::add(err.qdd, r.qdd[7], -e * w * w * c);
  }
  INFO("relative errors q " << err.q << ", qd " << err.qd << ", qdd " << err.qdd);
  CHECK(err.q <= 64 * kEps);
  CHECK(err.qd <= 64 * kEps);
  CHECK(err.qdd <= 64 * kEps);
  const double generated = generated_against_analyze<km::cam_flat>(rows);
  INFO("generated against analyze " << generated);
  CHECK(generated <= 1e-12);
}

TEST_CASE("followers: an eccentric cam under a roller follower", "[followers]") {
  // cam_roller.yaml: e 0.02, R 0.05, r 0.015, omega 2.
  const double e = 0.02, rr = 0.065, w = 2;
  const auto model = kc::CompiledModel::from_file(mechanism("cam_roller"));
  const auto rows = analyze(*model, {0, 2 * kPi, 720});
  Error err;
  for (const auto& r : rows) {
    const double th = w * r.t;
    const RollerLift y = roller_lift(e, rr, th);
    Error::add(err.q, r.q[4], y.y);
    Error::add(err.qd, r.qd[4], w * y.dy);
    Error::add(err.qdd, r.qdd[4], w * w * y.ddy);
    // The contact lies on the line of centres: on the cam at its angle, on the roller opposite.
    const double line = std::atan2(y.y - e * std::sin(th), -e * std::cos(th));
    Error::add(err.q, std::remainder(r.q[6] + th - line, 2 * kPi), 0);
    Error::add(err.q, std::remainder(r.q[7] - line - kPi, 2 * kPi), 0);
  }
  INFO("relative errors q " << err.q << ", qd " << err.qd << ", qdd " << err.qdd);
  CHECK(err.q <= 64 * kEps);
  CHECK(err.qd <= 64 * kEps);
  CHECK(err.qdd <= 64 * kEps);
  const double generated = generated_against_analyze<km::cam_roller>(rows);
  INFO("generated against analyze " << generated);
  CHECK(generated <= 1e-12);
}

TEST_CASE("followers: a pin in a turned parabolic slot follows the quadratic's root",
          "[followers]") {
  // parabolic_slot.yaml: k 0.5, alpha 0.3, X = 0.2 + 0.3 t; q: plate 0-2, crosshead 3-5, pin
  // 6-8, u 9. k s u^2 - c u + X = 0 (s, c of alpha), the root near X / c.
  const double k = 0.5, al = 0.3, sa = std::sin(al), ca = std::cos(al), v = 0.3;
  const auto model = kc::CompiledModel::from_file(mechanism("parabolic_slot"));
  const auto rows = analyze(*model, {0, 2, 400});
  Error err;
  for (const auto& r : rows) {
    const double X = 0.2 + v * r.t;
    const double u = 2 * X / (ca + std::sqrt(ca * ca - 4 * k * sa * X));  // no cancellation
    const double du = v / (ca - 2 * k * sa * u);
    const double ddu = 2 * k * sa * du * du / (ca - 2 * k * sa * u);
    Error::add(err.q, r.q[9], u);
    Error::add(err.qd, r.qd[9], du);
    Error::add(err.qdd, r.qdd[9], ddu);
    const double y = u * sa + k * u * u * ca, dy = (sa + 2 * k * u * ca) * du;
    Error::add(err.q, r.q[7], y);
    Error::add(err.qd, r.qd[7], dy);
    Error::add(err.qdd, r.qdd[7], (sa + 2 * k * u * ca) * ddu + 2 * k * ca * du * du);
  }
  INFO("relative errors q " << err.q << ", qd " << err.qd << ", qdd " << err.qdd);
  CHECK(err.q <= 64 * kEps);
  CHECK(err.qd <= 64 * kEps);
  CHECK(err.qdd <= 64 * kEps);
  const double generated = generated_against_analyze<km::parabolic_slot>(rows);
  INFO("generated against analyze " << generated);
  CHECK(generated <= 1e-12);
}

TEST_CASE("followers: the disc cam's follower reproduces its dwell-rise-dwell-return law",
          "[followers]") {
  // examples/cams/disc_cam.yaml: Rb 0.04, r 0.01, h 0.015, rise over [0, 2 pi/3], return over
  // [pi, 5 pi/3], omega 1. The grid lands on each boundary of the law (every 60th step).
  const double Rb = 0.04, r = 0.01, h = 0.015, b = 2 * kPi / 3, th2 = kPi;
  // The cycloidal law and its derivatives, clamped, written out here.
  const auto law = [](double x, int order) {
    if (x <= 0 || x >= 1) return order == 0 && x >= 1 ? 1.0 : 0.0;
    if (order == 0) return x - std::sin(2 * kPi * x) / (2 * kPi);
    if (order == 1) return 1 - std::cos(2 * kPi * x);
    return 2 * kPi * std::sin(2 * kPi * x);
  };
  const auto lift = [&](double th, int order) {
    return h * (law(th / b, order) / std::pow(b, order) -
                law((th - th2) / b, order) / std::pow(b, order));
  };
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/cams/disc_cam.yaml");
  const auto rows = analyze(*model, {0, 2 * kPi, 360});
  REQUIRE(rows.size() == 361);
  Error err;
  double top = 0;
  for (const auto& r0 : rows) {
    const double th = r0.t;
    Error::add(err.q, r0.q[4], Rb + r + lift(th, 0));
    Error::add(err.qd, r0.qd[4], lift(th, 1));
    Error::add(err.qdd, r0.qdd[4], lift(th, 2));
    Error::add(err.q, r0.outputs[0][0], lift(th, 0));
    top = std::max(top, r0.q[4]);
  }
  INFO("relative errors q " << err.q << ", qd " << err.qd << ", qdd " << err.qdd);
  CHECK(top == Approx(Rb + r + h).epsilon(1e-15));
  CHECK(err.q <= 64 * kEps);
  CHECK(err.qd <= 64 * kEps);
  CHECK(err.qdd <= 256 * kEps);
  const double generated = generated_against_analyze<km::disc_cam>(rows);
  INFO("generated against analyze " << generated);
  CHECK(generated <= 1e-12);
}

TEST_CASE("followers: the slot example's plate and pin follow the closed form", "[followers]") {
  // examples/slots/slot.yaml: the crank's pin P = [d + rc cos t, rc sin t] lies on the slot
  // A(psi) [u, k u^2]: |P|^2 = u^2 + k^2 u^4 fixes u, then psi = angle(P) - angle([u, k u^2]).
  const double d = 0.3, rc = 0.1, k = 2;
  const auto model = kc::CompiledModel::from_file(std::string(KINEGEN_SOURCE_DIR) +
                                                  "/examples/slots/slot.yaml");
  const auto rows = analyze(*model, {0, 2 * kPi, 360});
  Error err;
  for (const auto& r : rows) {
    const double px = d + rc * std::cos(r.t), py = rc * std::sin(r.t);
    const double u2 = 2 * (px * px + py * py) / (1 + std::sqrt(1 + 4 * k * k * (px * px + py * py)));
    const double u = std::sqrt(u2);
    Error::add(err.q, r.q[6], u);
    Error::add(err.q, r.q[5], std::atan2(py, px) - std::atan2(k * u2, u));
  }
  INFO("relative error q " << err.q);
  CHECK(err.q <= 64 * kEps);
}

TEST_CASE("followers: check accepts the curve joints with all three methods", "[followers]") {
  for (const std::string& file :
       {mechanism("cam_flat"), mechanism("cam_roller"), mechanism("parabolic_slot"),
        std::string(KINEGEN_SOURCE_DIR) + "/examples/cams/disc_cam.yaml",
        std::string(KINEGEN_SOURCE_DIR) + "/examples/slots/slot.yaml"}) {
    INFO(file);
    const auto model = kc::CompiledModel::from_file(file);
    kc::CheckOptions options;
    options.samples = 10;
    const auto rows = kc::check_derivatives(*model, options);
    REQUIRE(rows.size() == 9);
    std::vector<std::string> methods;
    for (const auto& r : rows) {
      INFO(r.block << " " << r.method << " rel " << r.max_rel << " bound " << r.bound);
      CHECK(r.ok());
      methods.push_back(r.method);
    }
    CHECK(std::count(methods.begin(), methods.end(), "complex-step") == 3);
    CHECK(std::count(methods.begin(), methods.end(), "central-difference") == 3);
    CHECK(std::count(methods.begin(), methods.end(), "cln-40") == 3);
  }
}

TEST_CASE("followers: the extra coordinates' CSV columns, header comment and kinds",
          "[followers]") {
  const auto model = kc::CompiledModel::from_file(mechanism("cam_flat"));
  const std::string header = kc::csv_header(model->mechanism());
  CHECK(header.find(",follower.alpha,a,a.v,a.a,b,b.v,b.a\n") != std::string::npos);
  const auto& kinds = model->symbolic().coordinate_kinds;
  REQUIRE(kinds.size() == 8);
  CHECK(kinds[6] == kinegen::CoordinateKind::kAngle);
  CHECK(kinds[7] == kinegen::CoordinateKind::kLength);
  CHECK(km::cam_flat::coordinate_kinds[6] == 1);
  CHECK(km::cam_flat::coordinate_kinds[7] == 0);
  CHECK(km::parabolic_slot::nq == 10);
  // One CSV row: the coordinate's value, rate and acceleration after the bodies'.
  const auto rows = analyze(*model, {0, 0, 0});
  const std::string line = kc::csv_row(rows[0], 2);
  CHECK(std::count(line.begin(), line.end(), ',') ==
        std::count(header.begin(), header.end(), ','));
}

TEST_CASE("followers: the cam's normal force is the spring plus the follower's inertia",
          "[followers][forces]") {
  // cam_roller.yaml: m 0.4, a compression spring k 200, L0 0.2 from (0, H = 0.2) on the
  // follower's origin, no gravity. The guide takes x, so vertically
  // fn n_y = m ydd + k (L0 - (H - y)), with n the unit line of centres, n_y = S / (R + r).
  // At omega 2 the spring holds the contact; at omega 50 the follower's deceleration over the
  // top exceeds the spring (m e omega^2 = 20 N > 17 N) and fn turns negative there.
  const double e = 0.02, rr = 0.065, m = 0.4, k = 200, L0 = 0.2, H = 0.2;
  for (const double w : {2.0, 50.0}) {
    INFO("omega " << w);
    std::ostringstream value;
    value.precision(17);
    value << w;
    const auto model = kc::CompiledModel::from_file(mechanism("cam_roller"), {{"omega", value.str()}});
    const kc::ForceModel forces = kc::forces_for_analysis(*model);
    kc::ForceSolver solver(*model, forces);
    const auto names = kc::force_columns(model->mechanism());
    const int fn = column(names, "contact.fn"), fx = column(names, "contact.fx"),
              fy = column(names, "contact.fy");
    CHECK(fn == fy + 2);  // after contact.tz
    const auto rows = analyze(*model, {0, 2 * kPi / w, 360});
    double worst = 0, largest = 0, generated = 0;
    int negative = 0, negative_truth = 0;
    km::cam_roller::Params p{};
    p.omega = w;
    for (const auto& r : rows) {
      std::vector<double> cols;
      REQUIRE(solver.solve(r.t, r.q, r.qd, r.qdd, cols));
      const double th = w * r.t;
      const RollerLift y = roller_lift(e, rr, th);
      const double S = std::sqrt(rr * rr - e * e * std::cos(th) * std::cos(th));
      const double truth = (m * w * w * y.ddy + k * (L0 - (H - y.y))) * rr / S;
      worst = std::max(worst, std::abs(cols[fn] - truth));
      largest = std::max(largest, std::abs(truth));
      // The force on the follower is fn along the line of centres.
      const double nx = -e * std::cos(th) / rr, ny = S / rr;
      worst = std::max(worst, std::abs(cols[fx] - truth * nx));
      worst = std::max(worst, std::abs(cols[fy] - truth * ny));
      negative += cols[fn] < 0;
      negative_truth += truth < 0;
      double lambda[km::cam_roller::nc], g[km::cam_roller::num_force_columns];
      REQUIRE(km::cam_roller::solve_forces(r.q.data(), r.qd.data(), r.qdd.data(), r.t, p, lambda,
                                           km::cam_roller::BlockOptions{})
                  .status == 0);
      km::cam_roller::force_columns(r.q.data(), r.t, p, lambda, g);
      for (int c = 0; c < km::cam_roller::num_force_columns; ++c)
        generated = std::max(generated, std::abs(g[c] - cols[c]));
    }
    INFO("largest error " << worst << " of forces up to " << largest << "; generated against "
                          << "analyze " << generated << "; rows with fn < 0: " << negative);
    CHECK(worst <= 1e-12 * largest);
    CHECK(generated <= 1e-12 * largest);
    CHECK(negative == negative_truth);
    if (w == 2.0) CHECK(negative == 0);
    if (w == 50.0) CHECK(negative > 0);
  }
}

namespace {

// A cam and a flat follower, each key on its own line so a case can name the line it breaks.
const std::string kCam = R"Y(name: cam
bodies:
  - name: cam
    q0: [0, 0, 0]
  - name: follower
    q0: [0, 0.07, 0]
coordinates:
  - name: a
    q0: 1.6
    kind: angle
  - name: b
    q0: 0
joints:
  - type: revolute
    i: ground
    j: cam
  - type: translational
    i: ground
    j: follower
    vi: [0, 1]
  - type: cam_follower
    i: cam
    curve_i: ["0.02 + 0.05*cos(a)", "0.05*sin(a)"]
    coordinate_i: a
    j: follower
    curve_j: ["b", "0"]
    coordinate_j: b
drivers:
  - type: absolute_angle
    body: cam
    f: t
)Y";

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

int line_of(const std::string& text, const std::string& what) {
  const auto at = text.find(what);
  REQUIRE(at != std::string::npos);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

fs::path scratch(const std::string& name) { return kinegen::test::scratch_dir("followers", name); }

}  // namespace

TEST_CASE("followers: hostile coordinates and curves give one error line, exit 2, no output",
          "[followers][hostile]") {
  struct Case {
    const char* name;
    std::string text;
    std::string at;       // text on the line the message must name
    const char* message;  // a phrase of it
  };
  const std::string extra = "  - name: b\n    q0: 0\n  - name: w\n    q0: 0\n";
  const std::vector<Case> cases = {
      {"undeclared_coordinate", replaced(kCam, "coordinate_j: b", "coordinate_j: c"),
       "coordinate_j: c", "unknown coordinate 'c'"},
      {"unused_coordinate", replaced(kCam, "  - name: b\n    q0: 0\n", extra), "name: w",
       "no joint or driver equation uses it"},
      {"bad_kind", replaced(kCam, "kind: angle", "kind: radians"), "kind: radians",
       "kind must be length, angle or scalar"},
      {"duplicate_coordinate", replaced(kCam, "name: b\n", "name: a\n"), "name: a\n    q0: 0",
       "duplicate coordinate name"},
      {"coordinate_named_like_a_body",
       replaced(replaced(kCam, "name: b\n", "name: cam\n"), "coordinate_j: b", "coordinate_j: cam"),
       "name: cam\n    q0: 0\n", "clashes"},
      {"coordinate_named_like_a_body_coordinate",
       replaced(replaced(kCam, "name: b\n", "name: x_cam\n"), "coordinate_j: b",
                "coordinate_j: x_cam"),
       "name: x_cam", "clashes"},
      {"curve_uses_t", replaced(kCam, "\"0.05*sin(a)\"", "\"0.05*sin(a) + t\""),
       "curve_i: [", "uses t"},
      {"curve_uses_another_coordinate", replaced(kCam, "curve_j: [\"b\"", "curve_j: [\"b + a\""),
       "curve_j: [", "may use only its coordinate 'b'"},
      {"curve_uses_a_body_coordinate", replaced(kCam, "curve_j: [\"b\"", "curve_j: [\"b + x_cam\""),
       "curve_j: [", "uses 'x_cam'"},
      {"curve_not_regular", replaced(kCam, "curve_j: [\"b\", \"0\"]", "curve_j: [\"b^2\", \"b^3\"]"),
       "curve_j: [", "not regular at b = 0"},
      {"same_coordinate_twice", replaced(kCam, "coordinate_j: b", "coordinate_j: a"),
       "type: cam_follower", "must be different coordinates"},
      {"curve_not_a_vector", replaced(kCam, "curve_j: [\"b\", \"0\"]", "curve_j: \"b\""),
       "curve_j: \"b\"", "expected a vector of 2 numbers"},
      {"missing_curve", replaced(kCam, "    curve_j: [\"b\", \"0\"]\n", ""), "type: cam_follower",
       "missing key 'curve_j'"},
  };
  for (const Case& c : cases) {
    SECTION(c.name) {
      const fs::path dir = scratch(c.name);
      const fs::path mech = dir / "m.yaml", csv = dir / "m.csv", out = dir / "out";
      fs::create_directories(out);
      std::ofstream(mech) << c.text;
      const std::string where =
          "error: " + mech.string() + ":" + std::to_string(line_of(c.text, c.at)) + ": ";
      for (const std::vector<std::string>& args :
           {std::vector<std::string>{"analyze", mech.string(), "--t0", "0", "--t1", "1",
                                     "--steps", "4", "-o", csv.string()},
            std::vector<std::string>{"generate", mech.string(), "-o", out.string()}}) {
        std::vector<std::string> argv{KINEGEN_EXE};
        argv.insert(argv.end(), args.begin(), args.end());
        const auto r = kinegen::test::run_command(argv);
        INFO(args[0] << ": " << r.err);
        CHECK(r.exit_code == 2);
        CHECK(r.err.rfind(where, 0) == 0);
        CHECK(r.err.find(c.message) != std::string::npos);
        CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
        CHECK(r.out.empty());
      }
      CHECK_FALSE(fs::exists(csv));
      CHECK(fs::is_empty(out));
    }
  }
  // The file the cases break analyzes.
  const fs::path dir = scratch("valid");
  std::ofstream(dir / "m.yaml") << kCam;
  const auto r = kinegen::test::run_command({KINEGEN_EXE, "analyze", (dir / "m.yaml").string(),
                                             "--t0", "0", "--t1", "1", "--steps", "4", "-o",
                                             (dir / "m.csv").string()});
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.err.empty());
}

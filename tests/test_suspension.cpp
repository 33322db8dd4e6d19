// The `suspension:` block (docs/format.md, Suspension analysis) and Bricard's linkage, each
// against a truth of its own: the double wishbone's toe and camber from a small solve of the
// hardpoints' distance equations written here (not kinegen's joint equations); every
// suspension output's rate and acceleration against central differences of its value and
// rate; a wheel steered about a vertical axis against closed forms on both sides; the input
// errors; Bricard's redundant linkage against a loop closure by products of rotations about
// its joint axes.
#include <Eigen/Dense>
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "support/cli.hpp"
#include "support/csv_columns.hpp"
#include "support/files.hpp"

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Columns = std::map<std::string, std::vector<double>>;

std::string source(const std::string& path) { return std::string(KINEGEN_SOURCE_DIR) + "/" + path; }

using kinegen::test::kinegen_cli;

Columns analyze(const std::string& file, double t0, double t1, int steps,
                const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args{"analyze", file,
                                "--t0",    std::to_string(t0),
                                "--t1",    std::to_string(t1),
                                "--steps", std::to_string(steps)};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = kinegen_cli(args);
  INFO(file << "\n" << r.err);
  REQUIRE(r.exit_code == 0);
  return kinegen::test::csv_columns(r.out);
}

// A rotation by `angle` about the unit `axis` (Rodrigues).
Matrix3d rotation(const Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

// ---- The double wishbone (examples/spatial/double_wishbone.yaml), solved here. -------------

struct Corner {
  Vector3d lower_front{0.22, 0.30, 0.14}, lower_rear{-0.22, 0.32, 0.16}, lbj{0.005, 0.72, 0.13};
  Vector3d upper_front{0.12, 0.42, 0.47}, upper_rear{-0.16, 0.43, 0.45}, ubj{-0.015, 0.67, 0.49};
  Vector3d tie_inner{-0.14, 0.33, 0.21}, tie_outer{-0.13, 0.70, 0.22}, wheel{0, 0.76, 0.30};
  Vector3d spin{0, 1, 0};
};

// The upright's frame from three of its points (a, b, c): columns e1 along a->b, e2 in the
// plane of the three, e3 normal to it.
Matrix3d triangle_frame(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d e1 = (b - a).normalized();
  const Vector3d e2 = ((c - a) - (c - a).dot(e1) * e1).normalized();
  Matrix3d f;
  f << e1, e2, e1.cross(e2);
  return f;
}

// The pose of the upright for the arms' angles and the tie rod's outer ball: what the distance
// equations below need. x = [lower arm angle, upper arm angle, tie rod outer ball (3)].
struct UprightPose {
  Vector3d lbj, ubj, tie_outer;
  Matrix3d turn;  // the upright's rotation from the design position
  Vector3d wheel, spin;
};

UprightPose pose_of(const Corner& c, const Eigen::Matrix<double, 5, 1>& x) {
  UprightPose p;
  p.lbj = c.lower_front + rotation(c.lower_rear - c.lower_front, x[0]) * (c.lbj - c.lower_front);
  p.ubj = c.upper_front + rotation(c.upper_rear - c.upper_front, x[1]) * (c.ubj - c.upper_front);
  p.tie_outer = x.tail<3>();
  p.turn = triangle_frame(p.lbj, p.ubj, p.tie_outer) *
           triangle_frame(c.lbj, c.ubj, c.tie_outer).transpose();
  p.wheel = p.lbj + p.turn * (c.wheel - c.lbj);
  p.spin = p.turn * c.spin;
  return p;
}

// The rigid upright's three distances, the tie rod's length and the wheel centre's height.
Eigen::Matrix<double, 5, 1> residual(const Corner& c, const Eigen::Matrix<double, 5, 1>& x,
                                     double wheel_z) {
  const UprightPose p = pose_of(c, x);
  Eigen::Matrix<double, 5, 1> r;
  r << (p.ubj - p.lbj).norm() - (c.ubj - c.lbj).norm(),
      (p.tie_outer - p.lbj).norm() - (c.tie_outer - c.lbj).norm(),
      (p.tie_outer - p.ubj).norm() - (c.tie_outer - c.ubj).norm(),
      (p.tie_outer - c.tie_inner).norm() - (c.tie_outer - c.tie_inner).norm(),
      p.wheel.z() - wheel_z;
  return r;
}

// Newton on the five equations (Jacobian by central differences), from x.
void solve_corner(const Corner& c, double wheel_z, Eigen::Matrix<double, 5, 1>& x) {
  for (int it = 0; it < 50; ++it) {
    const auto r = residual(c, x, wheel_z);
    Eigen::Matrix<double, 5, 5> j;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> h = Eigen::Matrix<double, 5, 1>::Zero();
      h[k] = 1e-7;
      j.col(k) = (residual(c, x + h, wheel_z) - residual(c, x - h, wheel_z)) / 2e-7;
    }
    const Eigen::Matrix<double, 5, 1> dx = j.fullPivLu().solve(-r);
    x += dx;
    if (dx.norm() < 1e-15) break;
  }
  REQUIRE(residual(c, x, wheel_z).norm() < 1e-14);
}

TEST_CASE("suspension: the double wishbone's toe and camber against a solve of its hardpoints",
          "[suspension]") {
  const auto col = analyze(source("examples/spatial/double_wishbone.yaml"), 0, 1, 40);
  const Corner corner;
  // From the design position (t = 0.5) each way, each solve from the one before.
  const std::size_t n = col.at("t").size();
  std::vector<UprightPose> poses(n);
  for (int direction : {-1, 1}) {
    Eigen::Matrix<double, 5, 1> x;
    x << 0, 0, corner.tie_outer;
    for (int k = 20; k >= 0 && k <= 40; k += direction) {
      const double t = col.at("t")[k];
      solve_corner(corner, 0.30 + 0.08 * (2 * t - 1), x);
      poses[k] = pose_of(corner, x);
    }
  }
  double worst_angle = 0, worst_length = 0, toe_lo = 1, toe_hi = -1, camber_lo = 1, camber_hi = -1;
  for (std::size_t k = 0; k < n; ++k) {
    const UprightPose& p = poses[k];
    const Vector3d s = p.spin.normalized(), axis = p.ubj - p.lbj;
    const double toe = std::atan2(s.x(), s.y()), camber = -std::asin(s.z());
    toe_lo = std::min(toe_lo, toe);
    toe_hi = std::max(toe_hi, toe);
    camber_lo = std::min(camber_lo, camber);
    camber_hi = std::max(camber_hi, camber);
    worst_angle = std::max({worst_angle, std::abs(col.at("toe")[k] - toe),
                            std::abs(col.at("camber")[k] - camber),
                            std::abs(col.at("caster")[k] - std::atan2(-axis.x(), axis.z())),
                            std::abs(col.at("kpi")[k] - std::atan2(-axis.y(), axis.z()))});
    // The contact point: down from the wheel centre in the wheel's plane.
    const Vector3d down = (s.z() * s - Vector3d::UnitZ()).normalized();
    const Vector3d contact = p.wheel + 0.30 * down;
    const Vector3d ground = p.lbj + (contact.z() - p.lbj.z()) / axis.z() * axis;
    worst_length = std::max({worst_length, std::abs(col.at("contact_x")[k] - contact.x()),
                             std::abs(col.at("contact_y")[k] - contact.y()),
                             std::abs(col.at("contact_z")[k] - contact.z()),
                             std::abs(col.at("scrub_radius")[k] - (contact.y() - ground.y())),
                             std::abs(col.at("trail")[k] - (ground.x() - contact.x())),
                             std::abs(col.at("wheel_travel")[k] - (p.wheel.z() - 0.30)),
                             std::abs(col.at("upright.x")[k] - (p.lbj - p.turn * corner.lbj).x())});
  }
  const Vector3d design_contact{0, 0.76, 0};
  double worst_track = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const Vector3d s = poses[k].spin.normalized();
    const Vector3d contact = poses[k].wheel + 0.30 * (s.z() * s - Vector3d::UnitZ()).normalized();
    worst_track = std::max(
        worst_track, std::abs(col.at("track_change")[k] - (contact.y() - design_contact.y())));
  }
  INFO("toe " << toe_lo << " .. " << toe_hi << ", camber " << camber_lo << " .. " << camber_hi
              << " rad; worst " << worst_angle << " rad, " << worst_length << " m, track "
              << worst_track);
  CHECK(worst_angle < 1e-10);
  CHECK(worst_length < 1e-10);
  CHECK(worst_track < 1e-10);
  // The travel moves the wheel: the check above is not of a still corner.
  CHECK(toe_hi - toe_lo > 1e-3);
  CHECK(camber_hi - camber_lo > 1e-2);
}

// Central differences of a column at the inner rows, against its derivative column.
double worst_difference(const std::vector<double>& t, const std::vector<double>& value,
                        const std::vector<double>& rate) {
  double worst = 0, scale = 0;
  for (double r : rate) scale = std::max(scale, std::abs(r));
  for (std::size_t k = 1; k + 1 < t.size(); ++k)
    worst =
        std::max(worst, std::abs((value[k + 1] - value[k - 1]) / (t[k + 1] - t[k - 1]) - rate[k]));
  return worst / std::max(scale, 1e-3);
}

TEST_CASE("suspension: every output's rate and acceleration against central differences",
          "[suspension]") {
  const char* names[] = {"toe",       "camber",       "caster",      "kpi",
                         "contact_x", "contact_y",    "contact_z",   "scrub_radius",
                         "trail",     "wheel_travel", "track_change"};
  // Bump with the rack held, then with the rack moving too.
  const std::string example = source("examples/spatial/double_wishbone.yaml");
  std::string steering = kinegen::test::read_text(example);
  const std::string rack = "f: \"rack\"";
  REQUIRE(steering.find(rack) != std::string::npos);
  steering.replace(steering.find(rack), rack.size(), "f: \"0.02*sin(3*t)\"");
  const auto steered = kinegen::test::scratch_dir("suspension", "rates") / "steering.yaml";
  kinegen::test::write_text(steered, steering);
  for (const std::string& file : {example, steered.string()}) {
    const auto col = analyze(file, 0, 1, 2000);
    const auto& t = col.at("t");
    for (const char* name : names) {
      const std::string n = name;
      INFO(n);
      CHECK(worst_difference(t, col.at(n), col.at(n + ".v")) < 1e-5);
      CHECK(worst_difference(t, col.at(n + ".v"), col.at(n + ".a")) < 1e-5);
    }
    // The motion ratio: -(dL/dt) / (d wheel_travel/dt), by differences of the values.
    const auto& ratio = col.at("spring.motion_ratio");
    double worst = 0;
    for (std::size_t k = 1; k + 1 < t.size(); ++k) {
      const double dl = col.at("spring")[k + 1] - col.at("spring")[k - 1];
      const double dw = col.at("wheel_travel")[k + 1] - col.at("wheel_travel")[k - 1];
      if (std::abs(dw) < 1e-7) continue;
      worst = std::max(worst, std::abs(ratio[k] + dl / dw));
    }
    CHECK(worst < 1e-5);
  }
}

// A wheel steered by theta = 0.3 t about a vertical axis through (0, +-0.7) with a built-in
// camber c: toe, camber, scrub radius and trail in closed form, on either side.
std::string steered_wheel(const char* side, double c) {
  const double y = std::string(side) == "left" ? 1 : -1;
  std::ostringstream f;
  f.precision(17);
  f << "space: 3d\nname: steered\nparameters: {c: " << c << "}\nbodies:\n  - {name: hub}\n"
    << "joints:\n  - {type: revolute, name: kingpin, i: ground, j: hub, si: [0, " << 0.7 * y
    << ", 0], sj: [0, " << 0.7 * y << ", 0], axis_i: [0, 0, 1], axis_j: [0, 0, 1]}\n"
    << "drivers:\n  - {type: revolute_angle, joint: kingpin, f: \"0.3*t\"}\n"
    << "points:\n  - {name: W, body: hub, s: [0, " << 0.75 * y << ", 0.3]}\n"
    << "  - {name: U, body: hub, s: [0, " << 0.7 * y << ", 0.5]}\n"
    << "  - {name: L, body: hub, s: [0, " << 0.7 * y << ", 0.1]}\n"
    << "vectors:\n  - {name: axle, body: hub, v: [0, " << 2 * y << "*cos(c), -2*sin(c)]}\n"
    << "suspension: {side: " << side
    << ", upright: hub, wheel_center: W, spin_axis: axle, steer_axis: [U, L], "
       "tire_radius: 0.28}\n";
  return f.str();
}

TEST_CASE("suspension: a wheel steered about a vertical axis against closed forms",
          "[suspension]") {
  const double c = 0.04, r = 0.28, offset = 0.05 - r * std::sin(c);
  const auto dir = kinegen::test::scratch_dir("suspension", "steered");
  for (const char* side : {"left", "right"}) {
    INFO(side);
    const double sigma = std::string(side) == "left" ? 1 : -1;
    const auto path = dir / (std::string(side) + ".yaml");
    kinegen::test::write_text(path, steered_wheel(side, c));
    const auto col = analyze(path.string(), -2, 2, 20);
    double worst = 0;
    for (std::size_t k = 0; k < col.at("t").size(); ++k) {
      const double th = 0.3 * col.at("t")[k];
      const auto at = [&](const char* name) { return col.at(name)[k]; };
      // Turning left (theta > 0) toes the left wheel out and the right wheel in.
      worst = std::max({worst, std::abs(at("toe") + sigma * th), std::abs(at("camber") - c),
                        std::abs(at("caster")), std::abs(at("kpi")),
                        std::abs(at("contact_z") - (0.3 - r * std::cos(c))),
                        std::abs(at("scrub_radius") - offset * std::cos(th)),
                        std::abs(at("trail") - sigma * offset * std::sin(th)),
                        std::abs(at("wheel_travel")),
                        std::abs(at("track_change") - offset * (std::cos(th) - 1)),
                        std::abs(at("toe.v") + sigma * 0.3), std::abs(at("toe.a")),
                        std::abs(at("scrub_radius.v") + offset * 0.3 * std::sin(th))});
    }
    CHECK(worst < 1e-12);
  }
}

TEST_CASE("suspension: bad input is one error line naming the item and its line, exit 2",
          "[suspension]") {
  const std::string base =
      kinegen::test::read_text(source("examples/spatial/double_wishbone.yaml"));
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = base;
    const auto at = s.find(from);
    REQUIRE(at != std::string::npos);
    return s.replace(at, from.size(), to);
  };
  // The line of `text` in the file.
  const auto line_of = [](const std::string& yaml, const std::string& text) {
    const auto at = yaml.find(text);
    return 1 + static_cast<int>(std::count(yaml.begin(), yaml.begin() + at, '\n'));
  };
  struct Bad {
    std::string what, yaml, line_text, says;
  };
  const std::vector<Bad> cases = {
      {"no upright", replaced("  upright: upright\n", ""), "side: left", "upright"},
      {"an unknown upright", replaced("upright: upright", "upright: knuckle"), "upright: knuckle",
       "unknown body"},
      {"a wheel centre off the upright", replaced("wheel_center: W", "wheel_center: seat"),
       "wheel_center: seat", "must be fixed in the upright"},
      {"an unknown spin axis", replaced("spin_axis: spin", "spin_axis: axle"), "spin_axis: axle",
       "no vector is named"},
      {"a zero tire radius", replaced("tire_radius: 0.30", "tire_radius: 0"), "tire_radius: 0",
       "must be positive"},
      {"a zero spin axis", replaced("v: [0, 1, 0]", "v: [0, 0, 0]"), "{name: spin",
       "must not be a zero vector"},
      {"a bad side", replaced("side: left", "side: front"), "side: front", "left"},
      {"an unknown spring", replaced("springs: [spring]", "springs: [coil]"), "springs: [coil]",
       "no output is named"},
      {"one steer point", replaced("steer_axis: [UBJ, LBJ]", "steer_axis: [UBJ]"),
       "steer_axis: [UBJ]", "two point names"},
      {"an output named toe", replaced("outputs:\n", "outputs:\n  toe: x_upright\n"),
       "suspension:", "clashes"},
      {"an unknown key", replaced("  design_t: 0.5\n", "  design_t: 0.5\n  rack: 1\n"), "rack: 1",
       "rack"},
      {"a planar file",
       "name: flat\nbodies:\n  - {name: a, q0: [0, 0, 0]}\nsuspension: {side: left}\n",
       "suspension:", "spatial files"},
  };
  const auto dir = kinegen::test::scratch_dir("suspension", "bad_input");
  for (const Bad& c : cases) {
    INFO(c.what << "\n" << c.yaml);
    const auto path = dir / "bad.yaml";
    kinegen::test::write_text(path, c.yaml);
    const auto r = kinegen_cli({"eval", path.string()});
    INFO(r.err);
    CHECK(r.exit_code == 2);
    CHECK(r.err.rfind("error: ", 0) == 0);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(r.err.find(path.string()) != std::string::npos);
    CHECK(r.err.find(":" + std::to_string(line_of(c.yaml, c.line_text)) + ":") !=
          std::string::npos);
    CHECK(r.err.find(c.says) != std::string::npos);
  }
}

TEST_CASE("suspension: a steer axis given lower point first is refused at the design position",
          "[suspension]") {
  // Read the other way round, k points down: caster and kpi would be half a turn off, with
  // no other sign of it.
  std::string yaml = kinegen::test::read_text(source("examples/spatial/double_wishbone.yaml"));
  const std::string from = "steer_axis: [UBJ, LBJ]";
  const auto at = yaml.find(from);
  REQUIRE(at != std::string::npos);
  yaml.replace(at, from.size(), "steer_axis: [LBJ, UBJ]");
  const auto dir = kinegen::test::scratch_dir("suspension", "steer_order");
  const auto path = dir / "swapped.yaml";
  const auto out = dir / "out.csv";
  kinegen::test::write_text(path, yaml);
  const auto r = kinegen_cli(
      {"analyze", path.string(), "--t0", "0", "--t1", "1", "--steps", "4", "-o", out.string()});
  INFO(r.err);
  CHECK(r.exit_code == 2);
  CHECK(r.err.rfind("error: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  const int line =
      1 + static_cast<int>(std::count(yaml.begin(), yaml.begin() + yaml.find("suspension:"), '\n'));
  CHECK(r.err.find(":" + std::to_string(line) + ":") != std::string::npos);
  CHECK(r.err.find("steer_axis: 'LBJ' is not above 'UBJ'") != std::string::npos);
  CHECK(!std::filesystem::exists(out));
}

// ---- Bricard's linkage (tests/mechanisms/spatial_bricard.yaml). -----------------------------

// Joint k's point and axis at the file's assembled pose; joint k joins body k - 1 (0: ground)
// and body k (6: ground).
struct Joint {
  Vector3d point, axis;
};
const std::vector<Joint>& bricard_joints() {
  static const std::vector<Joint> joints = {
      {{0, 0, 0}, {0, 0, 1}},
      {{0.68413446565163416, 0.72935590277144757, 0},
       {0.72935590277144757, -0.68413446565163416, 0}},
      {{0.40622318443374733, 0.4330746253620798, 0.91377389130380926},
       {-0.62514421285354593, -0.66646638142086845, -0.40622318443374705}},
      {{-0.3158655343483659, 0.72935590277144779, 1.538918104157355},
       {0.29628127740936799, -0.68413446565163405, 0.66646638142086845}},
      {{-0.59377681556625261, 0, 0.91377389130380915},
       {0.91377389130380926, 0, -0.40622318443374711}},
      {{-1, 0, 0}, {0, -1, 0}}};
  return joints;
}

// Body k's displacement from the assembled pose: the product of the turns about joints 1..k
// (each about its axis where it stands at that pose), as an affine map.
struct Displacement {
  Matrix3d r = Matrix3d::Identity();
  Vector3d p = Vector3d::Zero();
};
std::vector<Displacement> chain(const Eigen::Matrix<double, 6, 1>& angles) {
  std::vector<Displacement> out(1);
  for (int k = 0; k < 6; ++k) {
    const Joint& j = bricard_joints()[k];
    const Matrix3d turn = rotation(j.axis, angles[k]);
    Displacement d;
    d.r = out.back().r * turn;
    d.p = out.back().r * (j.point - turn * j.point) + out.back().p;
    out.push_back(d);
  }
  return out;  // out[k]: body k; out[6] must be the identity (the loop closes)
}

// The loop's closure: the last displacement's rotation and translation, 12 numbers.
Eigen::Matrix<double, 12, 1> closure(double first, const Eigen::Matrix<double, 5, 1>& rest) {
  Eigen::Matrix<double, 6, 1> a;
  a << first, rest;
  const Displacement d = chain(a).back();
  Eigen::Matrix<double, 12, 1> r;
  const Matrix3d off = d.r - Matrix3d::Identity();
  r << Eigen::Map<const Eigen::Matrix<double, 9, 1>>(off.data()), d.p;
  return r;
}

TEST_CASE("Bricard's linkage is solved through its redundant row against a loop closure",
          "[suspension][spatial]") {
  // From half a radian before the assembled pose to 1.1 after it (near 1.28 the linkage folds
  // into a pose where joint 1 cannot drive it further).
  const auto r = kinegen_cli({"analyze", source("tests/mechanisms/spatial_bricard.yaml"), "--t0",
                              "-0.5", "--t1", "1.1", "--steps", "32"});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  // One warning that names the dependent row.
  CHECK(r.err.rfind("warning: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find("redundant") != std::string::npos);
  CHECK(r.err.find("r6") != std::string::npos);
  const auto col = kinegen::test::csv_columns(r.out);
  // Gauss-Newton on the 12 closure equations in the other 5 angles, from `rest`.
  Eigen::Matrix<double, 5, 1> rest = Eigen::Matrix<double, 5, 1>::Zero();
  const auto close = [&](double first) {
    for (int it = 0; it < 50; ++it) {
      Eigen::Matrix<double, 12, 5> j;
      for (int c = 0; c < 5; ++c) {
        Eigen::Matrix<double, 5, 1> h = Eigen::Matrix<double, 5, 1>::Zero();
        h[c] = 1e-7;
        j.col(c) = (closure(first, rest + h) - closure(first, rest - h)) / 2e-7;
      }
      const Eigen::Matrix<double, 5, 1> step = j.colPivHouseholderQr().solve(-closure(first, rest));
      rest += step;
      if (step.norm() < 1e-15) break;
    }
    REQUIRE(closure(first, rest).norm() < 1e-13);
  };
  // From the assembled pose (all angles 0) to the first row's, in small steps.
  for (int i = 1; i <= 10; ++i) close(col.at("t")[0] * i / 10);
  double worst = 0, worst_turn = 0;
  for (std::size_t k = 0; k < col.at("t").size(); ++k) {
    const double first = col.at("t")[k];  // omega = 1
    close(first);
    Eigen::Matrix<double, 6, 1> a;
    a << first, rest;
    const auto bodies = chain(a);
    for (int b = 1; b <= 5; ++b) {
      const std::string name = "link" + std::to_string(b);
      const Vector3d origin{col.at(name + ".x")[k], col.at(name + ".y")[k], col.at(name + ".z")[k]};
      const Eigen::Quaterniond p(col.at(name + ".e0")[k], col.at(name + ".e1")[k],
                                 col.at(name + ".e2")[k], col.at(name + ".e3")[k]);
      worst = std::max(worst, (origin - bodies[b].p).cwiseAbs().maxCoeff());
      worst = std::max(worst, (p.toRotationMatrix() - bodies[b].r).cwiseAbs().maxCoeff());
    }
    worst_turn = std::max(worst_turn, std::abs(rest[2]));
  }
  INFO("worst " << worst);
  CHECK(worst < 1e-10);
  CHECK(worst_turn > 0.1);  // the linkage moved
}

}  // namespace

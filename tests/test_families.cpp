// The small members of the scalable mechanism families (scripts/mechanism_family.py, committed
// as tests/mechanisms/<family>_<N>.yaml) analyzed from the command line against their closed
// forms: each assembles at q0 and follows the motion its geometry implies.
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "support/run_command.hpp"

namespace {

namespace fs = std::filesystem;

const double kPi = std::acos(-1.0);

fs::path family_file(const std::string& name) {
  return fs::path(KINEGEN_SOURCE_DIR) / "tests" / "mechanisms" / (name + ".yaml");
}

// `kinegen analyze` over [t0, t1] as columns by name.
class Analysis {
 public:
  Analysis(const std::string& name, double t0, double t1, int steps) {
    const auto r = kinegen::test::run_command(
        {KINEGEN_EXE, "analyze", family_file(name).string(), "--t0", std::to_string(t0), "--t1",
         std::to_string(t1), "--steps", std::to_string(steps)});
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
    std::istringstream in(r.out);
    std::string line;
    REQUIRE(std::getline(in, line));
    std::vector<std::string> header = split(line);
    while (std::getline(in, line)) {
      std::vector<double> row;
      for (const auto& field : split(line)) row.push_back(std::strtod(field.c_str(), nullptr));
      REQUIRE(row.size() == header.size());
      rows_.push_back(row);
    }
    REQUIRE(rows_.size() == static_cast<std::size_t>(steps) + 1);
    for (std::size_t c = 0; c < header.size(); ++c) columns_[header[c]] = c;
  }

  std::size_t rows() const { return rows_.size(); }
  double t(std::size_t row) const { return rows_[row][0]; }
  double at(std::size_t row, const std::string& column) const {
    const auto it = columns_.find(column);
    INFO("column " << column);
    REQUIRE(it != columns_.end());
    return rows_[row][it->second];
  }

 private:
  static std::vector<std::string> split(const std::string& line) {
    std::vector<std::string> parts;
    std::istringstream in(line);
    std::string part;
    while (std::getline(in, part, ',')) parts.push_back(part);
    return parts;
  }

  std::vector<std::vector<double>> rows_;
  std::map<std::string, std::size_t> columns_;
};

// Expected position, velocity and acceleration of one coordinate (or point component).
struct Motion {
  double p, v, a;
};

void expect(const Analysis& an, std::size_t row, const std::string& name,
            const std::array<const char*, 3>& columns, const Motion& m, double margin = 1e-9) {
  INFO(name << " at t = " << an.t(row));
  CHECK(an.at(row, name + "." + columns[0]) == Approx(m.p).margin(margin));
  CHECK(an.at(row, name + "." + columns[1]) == Approx(m.v).margin(margin));
  CHECK(an.at(row, name + "." + columns[2]) == Approx(m.a).margin(margin));
}

const std::array<const char*, 3> kX = {"x", "vx", "ax"}, kY = {"y", "vy", "ay"},
                                 kPhi = {"phi", "omega", "alpha"};

}  // namespace

TEST_CASE("fourbar_chain_3: every side link keeps the crank's angle", "[families]") {
  // Parallelogram loops: c = 1, d = 1.5; crank angle pi/2 + amp sin(omega t), amp = 0.5.
  const double c = 1.0, d = 1.5, amp = 0.5;
  const Analysis an("fourbar_chain_3", 0, 2 * kPi, 48);
  for (std::size_t r = 0; r < an.rows(); ++r) {
    const double t = an.t(r);
    const Motion th{kPi / 2 + amp * std::sin(t), amp * std::cos(t), -amp * std::sin(t)};
    const double cs = std::cos(th.p), sn = std::sin(th.p);
    // The input tip c (cos th, sin th) and its derivatives.
    const Motion tip_x{c * cs, -c * sn * th.v, -c * (cs * th.v * th.v + sn * th.a)};
    const Motion tip_y{c * sn, c * cs * th.v, c * (-sn * th.v * th.v + cs * th.a)};
    expect(an, r, "crank", kPhi, th);
    expect(an, r, "crank", kX, {0, 0, 0});
    for (int k = 0; k < 3; ++k) {
      const std::string rocker = "rocker_" + std::to_string(k);
      const std::string coupler = "coupler_" + std::to_string(k);
      expect(an, r, rocker, kPhi, th);
      expect(an, r, rocker, kX, {(k + 1) * d, 0, 0});
      expect(an, r, rocker, kY, {0, 0, 0});
      expect(an, r, coupler, kPhi, {0, 0, 0});
      expect(an, r, coupler, kX, {k * d + tip_x.p, tip_x.v, tip_x.a});
      expect(an, r, coupler, kY, tip_y);
    }
    expect(an, r, "top", kX, {3 * d + tip_x.p, tip_x.v, tip_x.a});
    expect(an, r, "top", kY, tip_y);
  }
}

TEST_CASE("scissor_lift_3: cos(theta) = w / l, height N l sin(theta)", "[families]") {
  // Bars l = 1; the slider at w(t) = w0 + dw sin(omega t), w0 = 0.6, dw = 0.2, omega = 1.
  const double l = 1.0, w0 = 0.6, dw = 0.2;
  const int stages = 3;
  const Analysis an("scissor_lift_3", 0, 2 * kPi, 48);
  for (std::size_t r = 0; r < an.rows(); ++r) {
    const double t = an.t(r);
    const Motion w{w0 + dw * std::sin(t), dw * std::cos(t), -dw * std::sin(t)};
    // l cos(theta) = w, differentiated twice.
    const double th = std::acos(w.p / l), cs = std::cos(th), sn = std::sin(th);
    const double th_v = -w.v / (l * sn);
    const double th_a = -(w.a + l * cs * th_v * th_v) / (l * sn);
    // l sin(theta) and its derivatives: the height of one stage.
    const Motion h{l * sn, l * cs * th_v, l * (cs * th_a - sn * th_v * th_v)};
    for (int k = 0; k < stages; ++k) {
      const double level = k + 0.5;
      for (const char* bar : {"l_", "r_"}) {
        const std::string name = bar + std::to_string(k);
        expect(an, r, name, kX, {w.p / 2, w.v / 2, w.a / 2});
        expect(an, r, name, kY, {level * h.p, level * h.v, level * h.a});
      }
      expect(an, r, "l_" + std::to_string(k), kPhi, {th, th_v, th_a});
      expect(an, r, "r_" + std::to_string(k), kPhi, {kPi - th, -th_v, -th_a});
    }
    expect(an, r, "top_left", kX, {0, 0, 0});
    expect(an, r, "top_right", kX, w);
    for (const char* top : {"top_left", "top_right"})
      expect(an, r, top, kY, {stages * h.p, stages * h.v, stages * h.a});
  }
}

namespace {

// The closed chain as the four-bar it is: crank a, chord b, rocker c, ground d. Positions in
// closed form (law of cosines); the arc's links from the chord.
struct ChainPose {
  double crank, chord, rocker;
  double bx, by;  // the rocker tip
};

ChainPose chain_pose(double t) {
  const double a = 1.0, b = 3.5, c = 2.5, d = 3.0;
  const double th = t;  // omega = 1
  const double ax = a * std::cos(th), ay = a * std::sin(th);
  const double ex = d - ax, ey = -ay, e = std::hypot(ex, ey);
  const double alpha = std::acos((b * b + e * e - c * c) / (2 * b * e));
  ChainPose p;
  p.crank = th;
  p.chord = std::atan2(ey, ex) + alpha;  // B above the line A-O4
  p.bx = ax + b * std::cos(p.chord);
  p.by = ay + b * std::sin(p.chord);
  p.rocker = std::atan2(p.by, p.bx - d);
  return p;
}

// Central differences of a closed-form position in t: its velocity and acceleration.
Motion differentiate(const std::function<double(double)>& f, double t) {
  const double h1 = 1e-5, h2 = 1e-4;
  return {f(t), (f(t + h1) - f(t - h1)) / (2 * h1), (f(t + h2) - 2 * f(t) + f(t - h2)) / (h2 * h2)};
}

}  // namespace

TEST_CASE("closed_chain_4: the four-bar with the arc's chord as coupler", "[families]") {
  // Two coupler links bent by pi/2 with chord b = 3.5: each of length b sin(pi/4) / sin(pi/2).
  const double b = 3.5, bend = kPi / 2, ell = b * std::sin(bend / 2) / std::sin(bend);
  const Analysis an("closed_chain_4", 0, 2 * kPi, 72);
  for (std::size_t r = 0; r < an.rows(); ++r) {
    const double t = an.t(r);
    const ChainPose p = chain_pose(t);
    const auto rocker = [](double s) { return chain_pose(s).rocker; };
    const auto link0 = [&](double s) { return chain_pose(s).chord - bend / 2; };
    const auto link1_x = [&](double s) {
      return std::cos(s) + ell * std::cos(chain_pose(s).chord - bend / 2);
    };
    const auto link1_y = [&](double s) {
      return std::sin(s) + ell * std::sin(chain_pose(s).chord - bend / 2);
    };
    const auto bx = [](double s) { return chain_pose(s).bx; };
    const auto by = [](double s) { return chain_pose(s).by; };
    // Differences carry ~1e-8 (velocity) and ~1e-6 (acceleration) of error.
    const double margin = 1e-5;
    expect(an, r, "crank", kPhi, {t, 1, 0});
    const Motion phi_rocker = differentiate(rocker, t);
    // The rocker swings within (0, pi): no unwrapping is needed.
    expect(an, r, "rocker", kPhi, phi_rocker, margin);
    expect(an, r, "link_0", kX, {std::cos(t), -std::sin(t), -std::cos(t)});
    expect(an, r, "link_0", kY, {std::sin(t), std::cos(t), -std::sin(t)});
    const Motion phi0 = differentiate(link0, t);
    expect(an, r, "link_0", kPhi, phi0, margin);
    expect(an, r, "link_1", kPhi, {phi0.p + bend, phi0.v, phi0.a}, margin);
    expect(an, r, "link_1", kX, differentiate(link1_x, t), margin);
    expect(an, r, "link_1", kY, differentiate(link1_y, t), margin);
    expect(an, r, "B", kX, differentiate(bx, t), margin);
    expect(an, r, "B", kY, differentiate(by, t), margin);
    CHECK(std::hypot(p.bx - std::cos(t), p.by - std::sin(t)) == Approx(b));
  }
}

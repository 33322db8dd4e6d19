// `kinegen animate`: the SVG is rendered by headless Chromium (Debian `chromium`) to PNG,
// decoded with libpng, and must show the four-bar where its closed-form solution
// (tests/support/closed_form.hpp) puts it: the link colour along each link, not at the
// mirror images of those places. Also the animation's structure and the usage errors.
// Skips, with a message, where Chromium or libpng is missing (CI installs both).
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#ifdef KINEGEN_HAVE_PNG
#include <png.h>
#endif

#include "support/closed_form.hpp"
#include "support/files.hpp"
#include "support/run_command.hpp"

namespace fs = std::filesystem;
using kinegen::test::run_command;

namespace {

const std::string kFourBar = KINEGEN_SOURCE_DIR "/examples/four_bar.yaml";
constexpr int kSteps = 72;
const double kTwoPi = 2 * std::acos(-1.0);

fs::path scratch(const std::string& name) { return kinegen::test::scratch_dir("animate", name); }

std::string read(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double attribute(const std::string& svg, const std::string& name) {
  std::smatch m;
  REQUIRE(std::regex_search(svg, m, std::regex(name + "=\"([-0-9.e+]+)\"")));
  return std::stod(m[1].str());
}

std::string find_chromium() {
  if (const char* env = std::getenv("KINEGEN_CHROMIUM")) return env;
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"})
    if (fs::exists(p)) return p;
  return {};
}

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;
  std::array<int, 3> at(double x, double y) const {
    const int i = static_cast<int>(std::lround(x)), j = static_cast<int>(std::lround(y));
    if (i < 0 || j < 0 || i >= width || j >= height) return {-1, -1, -1};
    const unsigned char* p = &rgb[3 * (static_cast<std::size_t>(j) * width + i)];
    return {p[0], p[1], p[2]};
  }
};

#ifdef KINEGEN_HAVE_PNG
Image decode_png(const fs::path& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  REQUIRE(png_image_begin_read_from_file(&image, path.c_str()) != 0);
  image.format = PNG_FORMAT_RGB;
  Image out;
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  out.rgb.resize(PNG_IMAGE_SIZE(image));
  REQUIRE(png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr) != 0);
  return out;
}
#endif

// #1f77b4, the documented link colour, allowing for anti-aliasing at the edges.
bool is_link_colour(const std::array<int, 3>& c) {
  return std::abs(c[0] - 0x1f) <= 30 && std::abs(c[1] - 0x77) <= 30 && std::abs(c[2] - 0xb4) <= 30;
}

}  // namespace

TEST_CASE("animate: a still frame rendered by Chromium shows the links where they are",
          "[animate][chromium]") {
  const std::string chromium = find_chromium();
  if (chromium.empty()) {
    WARN("SKIPPED: chromium not found (apt-get install chromium, or set KINEGEN_CHROMIUM)");
    return;
  }
#ifndef KINEGEN_HAVE_PNG
  WARN("SKIPPED: built without libpng (apt-get install libpng-dev)");
  return;
#else
  for (const int frame : {10, 40}) {
    const fs::path dir = scratch("frame" + std::to_string(frame));
    const fs::path svg_file = dir / "four_bar.svg", png_file = dir / "four_bar.png";
    const auto gen = run_command({KINEGEN_EXE, "animate", kFourBar, "--t0", "0", "--t1",
                                  "6.283185307179586", "--steps", std::to_string(kSteps), "--frame",
                                  std::to_string(frame), "-o", svg_file.string()});
    INFO(gen.err);
    REQUIRE(gen.exit_code == 0);
    const std::string svg = read(svg_file);
    CHECK(svg.find("<animate") == std::string::npos);  // a still picture
    const double width = attribute(svg, "width"), height = attribute(svg, "height");
    const double scale = attribute(svg, "data-kinegen-scale");
    const double x0 = attribute(svg, "data-kinegen-x0"), y0 = attribute(svg, "data-kinegen-y0");

    const auto shot = run_command(
        {chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--hide-scrollbars", "--force-device-scale-factor=1",
         "--user-data-dir=" + (dir / "profile").string(), "--screenshot=" + png_file.string(),
         "--window-size=" + std::to_string(std::lround(width)) + "," +
             std::to_string(std::lround(height)),
         "file://" + svg_file.string()});
    INFO(shot.err);
    REQUIRE(fs::exists(png_file));
    const Image image = decode_png(png_file);
    REQUIRE(image.width == std::lround(width));
    REQUIRE(image.height == std::lround(height));

    // Where the closed form puts the links at this frame's time.
    const double t = kTwoPi * frame / kSteps;
    const auto st = kinegen::closed_form::four_bar_state(t);
    const kinegen::closed_form::FourBarParams p;
    const std::array<double, 2> o2{0, 0}, o4{p.d, 0}, a{st.q[3], st.q[4]};
    const std::array<double, 2> b{a[0] + p.b * std::cos(st.q[5]), a[1] + p.b * std::sin(st.q[5])};
    const std::array<std::array<std::array<double, 2>, 2>, 3> links{{{o2, a}, {a, b}, {o4, b}}};
    const auto px = [&](double x, double y) {
      return std::array<double, 2>{x0 + scale * x, y0 - scale * y};
    };
    int checked = 0;
    for (const auto& link : links)
      for (const double f : {0.3, 0.5, 0.7}) {
        const double x = link[0][0] + f * (link[1][0] - link[0][0]);
        const double y = link[0][1] + f * (link[1][1] - link[0][1]);
        const auto on = px(x, y);
        const auto off = px(x, -y);  // the mirror image in the ground line: empty here
        INFO("frame " << frame << " link point (" << x << ", " << y << ") at pixel (" << on[0]
                      << ", " << on[1] << ")");
        const auto c_on = image.at(on[0], on[1]), c_off = image.at(off[0], off[1]);
        INFO("colour there " << c_on[0] << "," << c_on[1] << "," << c_on[2] << "; mirrored "
                             << c_off[0] << "," << c_off[1] << "," << c_off[2]);
        CHECK(is_link_colour(c_on));
        CHECK_FALSE(is_link_colour(c_off));
        ++checked;
      }
    CHECK(checked == 9);
    // Away from the mechanism: the corners are background.
    CHECK(image.at(2, height - 3) == std::array<int, 3>{255, 255, 255});
    CHECK(image.at(width - 3, height - 3) == std::array<int, 3>{255, 255, 255});
  }
#endif
}

TEST_CASE("animate: the animation has one value per analysis row and loops", "[animate]") {
  const fs::path dir = scratch("animation");
  const fs::path svg_file = dir / "four_bar.svg";
  const auto r = run_command({KINEGEN_EXE, "animate", kFourBar, "--t0", "0", "--t1",
                              "6.283185307179586", "--steps", "36", "-o", svg_file.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const std::string svg = read(svg_file);
  CHECK(svg.rfind("<?xml", 0) == 0);
  CHECK(svg.find("</svg>") != std::string::npos);
  // Every <animate> loops over 37 values (one per row); a crank pin (cx) starts at the closed
  // form's A at t = 0 and is there again after one turn.
  const std::regex animate_re(
      "<animate attributeName=\"([a-z]+)\"[^>]*repeatCount=\"indefinite\"[^>]*values=\"([^\"]*)\"");
  int count = 0;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), animate_re);
       it != std::sregex_iterator(); ++it) {
    const std::string values = (*it)[2].str();
    CHECK(std::count(values.begin(), values.end(), ';') == 36);
    ++count;
  }
  CHECK(count > 10);
  // Traced path of the coupler point P: passes through the closed form's P at t = 0.
  const double scale = attribute(svg, "data-kinegen-scale");
  const double x0 = attribute(svg, "data-kinegen-x0"), y0 = attribute(svg, "data-kinegen-y0");
  const auto p0 = kinegen::closed_form::four_bar_coupler_point(0.0);
  char expected[64];
  std::snprintf(expected, sizeof expected, "%.2f,%.2f", x0 + scale * p0.r[0], y0 - scale * p0.r[1]);
  CHECK(svg.find(std::string("points=\"") + expected + " ") != std::string::npos);
}

TEST_CASE("animate: usage errors write nothing", "[animate]") {
  const fs::path dir = scratch("errors");
  const fs::path svg_file = dir / "out.svg";
  const auto r = run_command({KINEGEN_EXE, "animate", kFourBar, "--t0", "0", "--t1", "1", "--steps",
                              "10", "--frame", "11", "-o", svg_file.string()});
  CHECK(r.exit_code == 2);
  CHECK(r.err.rfind("error: ", 0) == 0);
  CHECK(r.err.find("--frame") != std::string::npos);
  CHECK_FALSE(fs::exists(svg_file));
  const auto q = run_command({KINEGEN_EXE, "animate", kFourBar, "--t0", "0", "--t1", "1", "--steps",
                              "10", "--quiet", "-o", svg_file.string()});
  CHECK(q.exit_code == 0);
  CHECK(q.err.empty());  // --quiet: not even the "wrote" line
  CHECK(fs::exists(svg_file));
}

TEST_CASE("animate: the analysis' warnings, silenced by --quiet", "[animate]") {
  // One of the double parallelogram's 13 equations is redundant: analyzed with a warning.
  const fs::path dir = scratch("warnings");
  const std::string mech =
      std::string(KINEGEN_SOURCE_DIR) + "/tests/stability/double_parallelogram.yaml";
  const std::string svg = (dir / "dp.svg").string();
  const auto r = run_command(
      {KINEGEN_EXE, "animate", mech, "--t0", "0.2", "--t1", "1", "--steps", "4", "-o", svg});
  INFO(r.err);
  CHECK(r.exit_code == 0);
  CHECK(r.err.find("warning: ") != std::string::npos);
  const auto q = run_command({KINEGEN_EXE, "animate", mech, "--t0", "0.2", "--t1", "1",
                              "--steps", "4", "-q", "-o", svg});
  CHECK(q.exit_code == 0);
  CHECK(q.err.empty());
}

namespace {

// The rows of a CSV file as numbers, after its header (returned in `header`).
std::vector<std::vector<double>> read_csv(const fs::path& path, std::vector<std::string>& header) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::vector<double>> rows;
  header.clear();
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (header.empty()) {
      header = cells;
      continue;
    }
    std::vector<double> row;
    for (const auto& cell : cells) row.push_back(std::stod(cell));
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

TEST_CASE("animate --forces: one arrow per joint, along its reaction, to one scale", "[animate]") {
  const fs::path dir = scratch("forces");
  const std::string mech = KINEGEN_SOURCE_DIR "/examples/forces/four_bar_balanced.yaml";
  const std::vector<std::string> grid = {"--t0", "0", "--t1", "6.283185307179586", "--steps", "36"};
  std::vector<std::string> analyze = {KINEGEN_EXE, "analyze", mech, "--forces", "-o",
                                      (dir / "forces.csv").string()};
  analyze.insert(analyze.end(), grid.begin(), grid.end());
  REQUIRE(run_command(analyze).exit_code == 0);
  std::vector<std::string> header;
  const auto rows = read_csv(dir / "forces.csv", header);
  REQUIRE(rows.size() == 37);
  const auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    REQUIRE(it != header.end());
    return static_cast<int>(it - header.begin());
  };
  const std::vector<std::string> joints = {"O2", "A", "B", "O4"};
  double largest = 0;
  for (const auto& row : rows)
    for (const auto& j : joints)
      largest = std::max(largest, std::hypot(row[column(j + ".fx")], row[column(j + ".fy")]));
  REQUIRE(largest > 0);
  for (const int frame : {0, 11, 25}) {
    const fs::path svg_file = dir / ("frame" + std::to_string(frame) + ".svg");
    std::vector<std::string> animate = {KINEGEN_EXE, "animate", mech, "--forces", "--frame",
                                        std::to_string(frame), "-o", svg_file.string()};
    animate.insert(animate.end(), grid.begin(), grid.end());
    const auto r = run_command(animate);
    INFO(r.err);
    REQUIRE(r.exit_code == 0);
    const std::string svg = read(svg_file);
    const double width = attribute(svg, "svg xmlns=\"http://www.w3.org/2000/svg\" width");
    const double height = attribute(svg, " height");
    // The largest reaction over the analysis is a quarter of the smaller side (the title's
    // 24 pixels apart): pixels per unit of force.
    const double per_force = 0.25 * std::min(width, height - 24) / largest;
    for (const auto& j : joints) {
      INFO("frame " << frame << ", joint " << j);
      // The comment names the joint's item, e.g. "joints[1] 'A' (revolute)".
      const auto at = svg.find("<!-- reaction of joints[");
      const auto named = svg.find("'" + j + "' (revolute) -->", at);
      REQUIRE(named != std::string::npos);
      const auto from = svg.find("points=\"", named);
      REQUIRE(from != std::string::npos);
      std::stringstream pts(svg.substr(from + 8, svg.find('"', from + 8) - from - 8));
      std::vector<std::array<double, 2>> p;
      for (std::string xy; pts >> xy;) {
        const auto comma = xy.find(',');
        p.push_back({std::stod(xy.substr(0, comma)), std::stod(xy.substr(comma + 1))});
      }
      REQUIRE(p.size() == 6);
      // Tail to tip (the 4th point) is the force in pixels, y down; to the SVG's 2 decimals.
      const double fx = rows[frame][column(j + ".fx")], fy = rows[frame][column(j + ".fy")];
      CHECK(p[3][0] - p[0][0] == Approx(per_force * fx).margin(0.02));
      CHECK(p[3][1] - p[0][1] == Approx(-per_force * fy).margin(0.02));
    }
  }
}

namespace {

// The first frame's value of `attribute` of the first element after `marker` in the SVG.
std::string after(const std::string& svg, const std::string& marker, const std::string& name) {
  const auto at = svg.find(marker);
  REQUIRE(at != std::string::npos);
  std::smatch m;
  const std::string rest = svg.substr(at);
  REQUIRE(std::regex_search(rest, m, std::regex(" " + name + "=\"([^\"]*)\"")));
  return m[1].str();
}

std::vector<std::array<double, 2>> pairs(const std::string& text) {
  std::vector<std::array<double, 2>> out;
  const std::regex pair_re("(-?[0-9.]+),(-?[0-9.]+)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), pair_re);
       it != std::sregex_iterator(); ++it)
    out.push_back({std::stod((*it)[1].str()), std::stod((*it)[2].str())});
  return out;
}

double distance(const std::array<double, 2>& a, double x, double y) {
  return std::hypot(a[0] - x, a[1] - y);
}

}  // namespace

TEST_CASE("animate --mode: a body whose only joint is at its origin is drawn, at its size",
          "[animate]") {
  // The pendulum of examples/dynamics without its named point: its rod has one joint, at its
  // frame's origin, and its centre of mass at [a, 0]. The mode swings it about the hanging rest
  // (theta = -pi/2): frame 0 is the rest, the centre of mass a = 0.5 below the pivot.
  const fs::path dir = scratch("mode_bare");
  const fs::path mech = dir / "bare.yaml", svg_file = dir / "bare.svg";
  std::ofstream(mech) << "name: bare\nparameters: {m: 1.0, a: 0.5, g: 9.81}\ngravity: [0, -g]\n"
                         "bodies:\n  - {name: rod, q0: [0, 0, 0], mass: m, inertia: 0.08, "
                         "com: [a, 0]}\njoints:\n  - {type: revolute, name: pivot, i: ground, "
                         "j: rod}\nfree:\n  - {type: absolute_angle, name: theta, body: rod, "
                         "value0: -1.5}\n";
  const auto r =
      run_command({KINEGEN_EXE, "animate", mech.string(), "--mode", "1", "-o", svg_file.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const std::string svg = read(svg_file);
  const double scale = attribute(svg, "data-kinegen-scale");
  const double x0 = attribute(svg, "data-kinegen-x0"), y0 = attribute(svg, "data-kinegen-y0");
  // The rod (0.5 to its centre of mass) between 100 px and the picture's 800 (was 7.2e11 px/m).
  CHECK(0.5 * scale > 100);
  CHECK(0.5 * scale < 800);
  // A bar from the pivot to the centre of mass, each end within 1 px.
  const auto bar = pairs(after(svg, "<!-- body rod -->", "points"));
  REQUIRE(bar.size() == 2);
  const double pivot = std::min(distance(bar[0], x0, y0), distance(bar[1], x0, y0));
  const double com =
      std::min(distance(bar[0], x0, y0 + 0.5 * scale), distance(bar[1], x0, y0 + 0.5 * scale));
  CHECK(pivot <= 1);
  CHECK(com <= 1);
}

TEST_CASE("animate --mode: a flywheel on its pivot is a disc there, its torsion spring a coil",
          "[animate]") {
  // Nothing but a wheel turning about its centre against a rotational spring: everything drawn
  // is at one place, which once made a view of 1e11 px/m.
  const fs::path dir = scratch("mode_flywheel");
  const fs::path mech = dir / "flywheel.yaml", svg_file = dir / "flywheel.svg";
  std::ofstream(mech) << "name: flywheel\nbodies:\n  - {name: wheel, q0: [0, 0, 0], mass: 2, "
                         "inertia: 0.05}\njoints:\n  - {type: revolute, name: axle, i: ground, "
                         "j: wheel}\nfree:\n  - {type: absolute_angle, name: theta, body: wheel, "
                         "value0: 0}\nforces:\n  - {type: rotational_spring_damper, name: "
                         "torsion, i: ground, j: wheel, stiffness: 20, damping: 0.1}\n";
  const auto r =
      run_command({KINEGEN_EXE, "animate", mech.string(), "--mode", "1", "-o", svg_file.string()});
  INFO(r.err);
  REQUIRE(r.exit_code == 0);
  const std::string svg = read(svg_file);
  const double scale = attribute(svg, "data-kinegen-scale");
  const double x0 = attribute(svg, "data-kinegen-x0"), y0 = attribute(svg, "data-kinegen-y0");
  CHECK(scale < 1e4);
  const auto disc = pairs(after(svg, "<!-- body wheel -->", "cx") + "," +
                          after(svg, "<!-- body wheel -->", "cy"));
  REQUIRE(disc.size() == 1);
  CHECK(distance(disc[0], x0, y0) <= 1);
  CHECK(after(svg, "<!-- body wheel -->", "r") == "11.00");
  // The coil starts 3 px from the axle.
  const auto coil =
      pairs(after(svg, "<!-- forces[0] 'torsion' (rotational_spring_damper) -->", "d"));
  REQUIRE(coil.size() > 10);
  CHECK(std::abs(distance(coil[0], x0, y0) - 3) <= 0.1);
}

TEST_CASE("animate --mode: --steps beyond what fits is refused before it costs memory",
          "[animate]") {
  const fs::path dir = scratch("mode_steps");
  const std::string svg = (dir / "m.svg").string();
  const std::string mech = KINEGEN_SOURCE_DIR "/examples/dynamics/pendulum.yaml";
  // 1 GiB of address space and 20 s of CPU: the frames once took 3.1 GB before bad_alloc.
  const fs::path out = dir / "out.txt", err = dir / "err.txt";
  kinegen::test::ChildProcess child(
      {KINEGEN_EXE, "animate", mech, "--mode", "1", "--steps", "2147483647", "-o", svg},
      "/dev/null", out.string(), err.string(), 20, rlim_t{1} << 30);
  const int code = child.wait();
  const std::string text = read(err);
  INFO(text);
  CHECK(code == 2);
  CHECK(text.rfind("error: ", 0) == 0);
  CHECK(std::count(text.begin(), text.end(), '\n') == 1);
  // The pendulum: 3 coordinates and one point, 5 numbers a frame.
  CHECK(text.find("--steps 2147483647: animate --mode keeps every frame in memory, at most "
                  "16777216 numbers (5 a frame here); --steps 3355442 is the most that fits") !=
        std::string::npos);
  CHECK_FALSE(fs::exists(svg));
}

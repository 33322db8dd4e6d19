#include "kinegen/codegen/io/animate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <vector>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"

namespace kinegen::codegen {

namespace {

using Eigen::Vector2d;

// A block sliding on a guide (Sketch::Slider), with its travel along dir over the analysis.
struct Slider : Sketch::Slider {
  double travel_min = 0, travel_max = 0;
};

constexpr const char* kGroundColour = "#555555";
constexpr const char* kPinStroke = "#222222";
constexpr const char* kSliderFill = "#9ecae1";
constexpr const char* kPointColour = "#d62728";
constexpr const char* kPathColour = "#ff7f0e";
constexpr const char* kGearColour = "#2ca02c";
constexpr double kPi = 3.14159265358979323846;

Vector2d rotate(double phi, const Vector2d& s) {
  const double c = std::cos(phi), sn = std::sin(phi);
  return {c * s[0] - sn * s[1], sn * s[0] + c * s[1]};
}

Vector2d world(const Eigen::VectorXd& q, int body, const Vector2d& s) {
  if (body == kGround) return s;
  const double phi = q[3 * body + 2];
  const auto r = point_position(&q[3 * body], std::cos(phi), std::sin(phi), s[0], s[1]);
  return {r[0], r[1]};
}

Vector2d local(const Eigen::VectorXd& q, int body, const Vector2d& r) {
  if (body == kGround) return r;
  return rotate(-q[3 * body + 2], r - q.segment<2>(3 * body));
}

std::string num(double v) { return format_number(v, NumberStyle::kPixels); }

std::string escape(const std::string& text) {
  std::string out;
  for (char ch : text) {
    switch (ch) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

void add_unique(std::vector<Vector2d>& points, const Vector2d& p, double tol) {
  for (const auto& x : points)
    if ((x - p).norm() <= tol) return;
  points.push_back(p);
}

class Picture {
 public:
  Picture(const CompiledModel& model, const AnimateOptions& options)
      : model_(model), options_(options) {}
  // Over given positions (kinegen view), for drawing() rather than render().
  Picture(const CompiledModel& model, std::vector<Eigen::VectorXd> q, int width)
      : model_(model), q_(std::move(q)) {
    options_.width = width;
  }

  AnimateDrawing drawing() {
    if (q_.empty()) throw UsageError("nothing to draw: no positions");
    if (options_.width < 50 || options_.width > 20000)
      throw UsageError("--width must be between 50 and 20000 pixels");
    collect();
    infer_attachments();
    fit();
    AnimateDrawing d;
    d.bodies = body_points_;
    d.pins = pins_;
    d.points = named_;
    d.ground_pivots = ground_pivots_;
    for (const auto& sl : sliders_) d.sliders.push_back({sl, sl.travel_min, sl.travel_max});
    for (const auto& l : pitch_lines_) d.pitch_lines.push_back({l, l.travel_min, l.travel_max});
    d.struts = struts_;
    d.pitch_circles = pitch_circles_;
    d.welds = welds_;
    d.curves = curves_;
    // The constraint behind each element: the kinds add theirs in constraint order.
    std::array<std::vector<const Constraint*>*, 7> by = {
        &d.pin_by, &d.slider_by, &d.strut_by, &d.circle_by, &d.line_by, &d.weld_by, &d.curve_by};
    for (const auto& [c, counts] : drawn_)
      for (std::size_t k = 0; k < by.size(); ++k) by[k]->resize(counts[k], c);
    d.scale = scale_, d.x0 = x0_, d.y0 = y0_, d.width = width_, d.height = height_;
    d.margin = kMargin, d.title = kTitle;
    d.colours = {{"link", kLinkColour},   {"background", kBackgroundColour},
                 {"force", kForceColour}, {"ground", kGroundColour},
                 {"pin", kPinStroke},     {"slider", kSliderFill},
                 {"point", kPointColour}, {"path", kPathColour},
                 {"gear", kGearColour}};
    return d;
  }

  std::string render() {
    solve();
    collect();
    infer_attachments();
    fit();
    return emit();
  }

 private:
  double number(const Expr& e, const std::string& item) const {
    return model_.geometry_number(e, item);
  }

  void solve() {
    const TimeGrid& g = options_.grid;
    if (g.steps < 0) throw UsageError("--steps must be 0 or more");
    if (!std::isfinite(g.t0) || !std::isfinite(g.t1))
      throw UsageError("--t0 and --t1 must be finite");
    if (options_.frame > g.steps)
      throw UsageError("--frame " + std::to_string(options_.frame) + " is beyond the last step (" +
                       std::to_string(g.steps) + ")");
    if (options_.width < 50 || options_.width > 20000)
      throw UsageError("--width must be between 50 and 20000 pixels");
    AnalysisOptions analysis;
    analysis.warn = options_.warn;
    if (options_.forces) {
      force_model_ = forces_for_analysis(model_, g.t0);
      analysis.forces = &force_model_;
    }
    run_analysis(
        model_, g,
        [&](const StateRow& row) {
          q_.push_back(row.q);
          t_.push_back(row.t);
          if (options_.forces) forces_.push_back(row.forces);
        },
        analysis);
    if (options_.forces) collect_reactions();
  }

  // Where each joint's J.fx, J.fy act (the body and point columns_from_lambda reports) and
  // their column in the force columns: after the drivers' efforts, three per joint.
  void collect_reactions() {
    const Mechanism& m = model_.mechanism();
    // The drivers' efforts come first: whatever force_columns does not give the joints.
    int reacting = 0;
    const auto columns = [](const Constraint& c) {
      return is_expression(c) ? 0 : 3 + static_cast<int>(c.kind->normal_force);  // fn
    };
    for (const Constraint& c : m.joints) reacting += columns(c);
    int column = static_cast<int>(force_columns(m).size()) - reacting;
    for (std::size_t j = 0; j < m.joints.size(); ++j) {
      const Constraint& c = m.joints[j];
      if (is_expression(c)) continue;
      const bool on_j = c.j != kGround;
      const auto& s = on_j ? force_model_.numbers.sj[j] : force_model_.numbers.si[j];
      reactions_.push_back({{on_j ? c.j : c.i, Vector2d(s[0], s[1])}, column, c.item});
      column += columns(c);
    }
    for (const auto& row : forces_)
      for (const auto& r : reactions_)
        largest_force_ = std::max(largest_force_, std::hypot(row[r.column], row[r.column + 1]));
  }

  void collect() {
    const Mechanism& m = model_.mechanism();
    body_points_.assign(m.bodies.size(), {});
    const double tol = 1e-9 * model_.symbolic().length_scale;
    const auto attach = [&](int body, const Vector2d& s) {
      if (body != kGround) add_unique(body_points_[body], s, tol);
    };
    // What each constraint's kind draws, kept in the order the kinds add it.
    Sketch sketch;
    for (const Constraint* c : m.constraints()) {
      if (!c->kind->draw) continue;
      DrawContext context{*c, [&](const Expr& e) { return number(e, c->item); }};
      context.curve_point = [&](const std::string& key, double u) { return curve_point(*c, key, u); };
      context.curve_range = [&](int k) { return curve_range(k); };
      c->kind->draw(context, sketch);
      drawn_.push_back({c,
                        {sketch.pins.size(), sketch.sliders.size(), sketch.struts.size(),
                         sketch.pitch_circles.size(), sketch.pitch_lines.size(),
                         sketch.welds.size(), sketch.curves.size()}});
    }
    for (const Attach& a : sketch.landmarks) attach(a.body, a.s);
    for (const Attach& a : sketch.pins) pins_.push_back(a);
    for (const Vector2d& g : sketch.ground_pivots) add_unique(ground_pivots_, g, tol);
    for (const Sketch::Slider& sl : sketch.sliders) sliders_.push_back({sl, 0, 0});
    struts_ = sketch.struts;
    pitch_circles_ = sketch.pitch_circles;
    for (const Sketch::Slider& l : sketch.pitch_lines) pitch_lines_.push_back({l, 0, 0});
    welds_ = sketch.welds;
    curves_ = sketch.curves;
    for (std::size_t p = 0; p < m.points.size(); ++p) {
      named_.push_back({m.points[p].body, model_.point_offsets()[p]});
      attach(m.points[p].body, model_.point_offsets()[p]);
    }
  }

  // A curve key of `c` at u (format 6.2): the curve reads only its own coordinate (checked
  // when it was derived), so every extra coordinate is set to u.
  Vector2d curve_point(const Constraint& c, const std::string& key, double u) const {
    const SymbolTable& s = model_.symbols();
    const Mechanism& m = model_.mechanism();
    const Vec2& v = c.curves.at(key);
    GiNaC::exmap at;
    for (std::size_t k = 0; k < m.coordinates.size(); ++k)
      at[s.q(m.coordinate_index(static_cast<int>(k)))] = u;
    const auto value = [&](const Expr& e) {
      const GiNaC::ex parsed = s.parse(e, Scope::kDriver, c.item + " " + key);
      return to_double(substitute_params(parsed, s, model_.symbolic().param_values).subs(at));
    };
    return {value(v.x), value(v.y)};
  }

  // Where to draw a curve in extra coordinate k: over its travel in the analysis with a
  // quarter of it as margin on either side; an angle (a cam's profile, a roller) a whole turn.
  std::pair<double, double> curve_range(int k) const {
    const int index = model_.mechanism().coordinate_index(k);
    double lo = q_[0][index], hi = lo;
    for (const auto& q : q_) lo = std::min(lo, q[index]), hi = std::max(hi, q[index]);
    if (model_.mechanism().coordinates[k].kind == CoordinateKind::kAngle) {
      const double mid = (lo + hi) / 2;
      return {mid - kPi, mid + kPi};
    }
    const double margin = std::max(0.25 * (hi - lo), 0.05 * model_.symbolic().coordinate_scales[index]);
    return {lo - margin, hi + margin};
  }

  // A point that keeps its place in a body's frame over the whole analysis belongs to that
  // body's drawing, whichever body the file put it on: this draws mechanisms written with
  // `expression` constraints, where the joints are not named.
  void infer_attachments() {
    const double tol = 1e-7 * model_.symbolic().length_scale;
    std::vector<Attach> candidates = named_;
    for (int b = 0; b < static_cast<int>(body_points_.size()); ++b) {
      candidates.push_back({b, Vector2d::Zero()});
      for (const auto& s : body_points_[b]) candidates.push_back({b, s});
    }
    const auto fixed_in = [&](int body, const Attach& c, Vector2d& s) {
      s = local(q_[0], body, world(q_[0], c.body, c.s));
      for (const auto& q : q_)
        if ((local(q, body, world(q, c.body, c.s)) - s).norm() > tol) return false;
      return true;
    };
    for (const auto& c : candidates) {
      if (q_.size() < 3) break;  // too few frames to tell what moves together
      Vector2d s;
      for (int b = 0; b < static_cast<int>(body_points_.size()); ++b)
        if (b != c.body && fixed_in(b, c, s)) add_unique(body_points_[b], s, tol);
      if (c.body != kGround && fixed_in(kGround, c, s)) add_unique(ground_pivots_, s, tol);
    }
    for (auto& pts : body_points_) {
      // Fewer than two points make no bar: the frame's origin is the body's other landmark.
      if (pts.size() < 2) add_unique(pts, Vector2d::Zero(), tol);
      // A simple polygon: points in angular order around their centroid.
      Vector2d centre = Vector2d::Zero();
      for (const auto& p : pts) centre += p;
      centre /= static_cast<double>(pts.size());
      std::stable_sort(pts.begin(), pts.end(), [&](const Vector2d& a, const Vector2d& b) {
        return std::atan2(a[1] - centre[1], a[0] - centre[0]) <
               std::atan2(b[1] - centre[1], b[0] - centre[0]);
      });
    }
  }

  // Extents of everything drawn, over every frame; the world-to-pixel map from them.
  void fit() {
    const double slack = 0.1 * model_.symbolic().length_scale;
    const auto travel = [&](Slider& sl, double margin) {
      sl.travel_min = 1e300;
      sl.travel_max = -1e300;
      for (const auto& q : q_) {
        const double u =
            (local(q, sl.guide, world(q, sl.point.body, sl.point.s)) - sl.origin).dot(sl.dir);
        sl.travel_min = std::min(sl.travel_min, u - margin);
        sl.travel_max = std::max(sl.travel_max, u + margin);
      }
    };
    for (auto& sl : sliders_) travel(sl, slack);
    // A rack's pitch line reaches past the pinion's pitch circle on either side.
    for (auto& l : pitch_lines_) {
      double radius = 0;
      for (const auto& c : pitch_circles_)
        if (c.centre.body == l.point.body && (c.centre.s - l.point.s).norm() == 0)
          radius = std::max(radius, c.radius);
      travel(l, slack + 1.5 * radius);
    }
    Eigen::AlignedBox2d box;
    for (const auto& q : q_) {
      for (int b = 0; b < static_cast<int>(body_points_.size()); ++b)
        for (const auto& s : body_points_[b]) box.extend(world(q, b, s));
      for (const auto& n : named_) box.extend(world(q, n.body, n.s));
      for (const auto* lines : {&sliders_, &pitch_lines_})
        for (const auto& sl : *lines) {
          box.extend(world(q, sl.guide, sl.origin + sl.travel_min * sl.dir));
          box.extend(world(q, sl.guide, sl.origin + sl.travel_max * sl.dir));
        }
      for (const auto& c : pitch_circles_) {
        const Vector2d centre = world(q, c.centre.body, c.centre.s);
        box.extend(centre - Vector2d(c.radius, c.radius));
        box.extend(centre + Vector2d(c.radius, c.radius));
      }
      for (const auto& c : curves_)
        for (const auto& p : c.points) box.extend(world(q, c.body, p));
    }
    for (const auto& g : ground_pivots_) box.extend(g);
    const Vector2d size = box.sizes().cwiseMax(1e-9 * model_.symbolic().length_scale);
    const double w = options_.width;
    const double inner = w - 2 * kMargin;
    scale_ = std::min(inner / size[0], inner / size[1]);
    width_ = size[0] * scale_ + 2 * kMargin;
    height_ = size[1] * scale_ + 2 * kMargin + kTitle;
    x0_ = kMargin - scale_ * box.min()[0];
    y0_ = kMargin + kTitle + scale_ * box.max()[1];
  }

  Vector2d px(const Vector2d& w) const { return {x0_ + scale_ * w[0], y0_ - scale_ * w[1]}; }

  bool still() const { return options_.frame >= 0; }
  int frames() const { return static_cast<int>(q_.size()); }

  // An attribute that changes from frame to frame: its value now, or an <animate> element.
  struct Animated {
    std::string name;
    std::function<std::string(int)> at;
  };

  void element(std::ostringstream& os, const std::string& tag, const std::string& fixed,
               const std::vector<Animated>& animated, const std::string& content = "") {
    const int shown = still() ? options_.frame : 0;
    os << "  <" << tag << " " << fixed;
    for (const auto& a : animated) os << " " << a.name << "=\"" << a.at(shown) << "\"";
    if (still() || frames() < 2) {
      os << (content.empty() ? "/>\n" : ">" + content + "</" + tag + ">\n");
      return;
    }
    os << ">" << content << "\n";
    for (const auto& a : animated) {
      os << "    <animate attributeName=\"" << a.name << "\" dur=\"" << num(duration_)
         << "s\" repeatCount=\"indefinite\" calcMode=\"linear\" values=\"";
      for (int f = 0; f < frames(); ++f) os << (f ? ";" : "") << a.at(f);
      os << "\"/>\n";
    }
    os << "  </" << tag << ">\n";
  }

  std::string points_at(int f, const std::function<std::vector<Vector2d>(int)>& shape) const {
    std::string s;
    for (const auto& p : shape(f))
      s += (s.empty() ? "" : " ") + num(px(p)[0]) + "," + num(px(p)[1]);
    return s;
  }

  std::string emit() {
    const TimeGrid& g = options_.grid;
    duration_ = options_.duration > 0 ? options_.duration : (g.t1 - g.t0 > 0 ? g.t1 - g.t0 : 4.0);
    const Mechanism& m = model_.mechanism();
    std::ostringstream os;
    os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
       << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << std::lround(width_)
       << "\" height=\"" << std::lround(height_) << "\" viewBox=\"0 0 " << std::lround(width_)
       << " " << std::lround(height_) << "\" data-kinegen-scale=\"" << format_number(scale_)
       << "\" data-kinegen-x0=\"" << format_number(x0_) << "\" data-kinegen-y0=\""
       << format_number(y0_) << "\">\n";
    os << "  <!-- Generated by kinegen "
       << "from " << escape(m.source) << ": "
       << (still() ? "frame " + std::to_string(options_.frame)
                   : std::to_string(frames()) + " frames")
       << " of t = " << format_number(g.t0) << " .. " << format_number(g.t1) << " -->\n";
    os << "  <rect width=\"100%\" height=\"100%\" fill=\"" << kBackgroundColour << "\"/>\n";
    const auto short_number = [](double v) { return format_number(v, NumberStyle::kShort); };
    const std::string title =
        m.name + (still() ? "   t = " + short_number(t_[options_.frame])
                          : "   t = " + short_number(g.t0) + " .. " + short_number(g.t1));
    os << "  <text x=\"" << num(kMargin) << "\" y=\"" << num(kTitle * 0.7)
       << "\" font-family=\"sans-serif\" font-size=\"14\" fill=\"#333333\">" << escape(title)
       << "</text>\n";

    // Traced paths of the named points (the whole analysis, also in a still frame).
    for (const auto& n : named_) {
      std::string pts;
      for (const auto& q : q_) {
        const Vector2d p = px(world(q, n.body, n.s));
        pts += (pts.empty() ? "" : " ") + num(p[0]) + "," + num(p[1]);
      }
      os << "  <polyline fill=\"none\" stroke=\"" << kPathColour
         << "\" stroke-width=\"1.5\" stroke-dasharray=\"4 3\" points=\"" << pts << "\"/>\n";
    }

    // Guides: fixed ones once; those on moving bodies (slots) move with them.
    for (const auto& sl : sliders_) {
      auto ends = [&, sl](int f) {
        return std::vector<Vector2d>{world(q_[f], sl.guide, sl.origin + sl.travel_min * sl.dir),
                                     world(q_[f], sl.guide, sl.origin + sl.travel_max * sl.dir)};
      };
      const std::string style = "fill=\"none\" stroke=\"" + std::string(kGroundColour) +
                                "\" stroke-width=\"3\" stroke-linecap=\"round\"";
      if (sl.guide == kGround) {
        os << "  <polyline " << style << " points=\"" << points_at(0, ends) << "\"/>\n";
        // Hatching on the guide's lower side (in pixels, y down).
        const Vector2d a = px(ends(0)[0]), b = px(ends(0)[1]);
        const Vector2d d = (b - a).normalized();
        Vector2d n(-d[1], d[0]);
        if (n[1] < 0) n = -n;
        const int count = std::max(2, static_cast<int>((b - a).norm() / 12));
        for (int k = 0; k <= count; ++k) {
          const Vector2d p = a + (b - a) * k / count, e = p + 8 * n - 6 * d;
          os << "  <line x1=\"" << num(p[0]) << "\" y1=\"" << num(p[1]) << "\" x2=\"" << num(e[0])
             << "\" y2=\"" << num(e[1]) << "\" stroke=\"" << kGroundColour
             << "\" stroke-width=\"1\"/>\n";
        }
      } else {
        element(os, "polyline", style,
                {{"points", [&, ends](int f) { return points_at(f, ends); }}});
      }
    }

    // Ground pivots: a triangle with hatching under the pin.
    for (const auto& g0 : ground_pivots_) {
      const Vector2d p = px(g0);
      os << "  <polygon fill=\"#dddddd\" stroke=\"" << kGroundColour
         << "\" stroke-width=\"1.5\" points=\"" << num(p[0]) << "," << num(p[1]) << " "
         << num(p[0] - 10) << "," << num(p[1] + 16) << " " << num(p[0] + 10) << ","
         << num(p[1] + 16) << "\"/>\n";
      for (int k = 0; k < 5; ++k) {
        const double x = p[0] - 12 + 6 * k;
        os << "  <line x1=\"" << num(x) << "\" y1=\"" << num(p[1] + 16) << "\" x2=\"" << num(x - 5)
           << "\" y2=\"" << num(p[1] + 22) << "\" stroke=\"" << kGroundColour
           << "\" stroke-width=\"1\"/>\n";
      }
    }

    // Struts of distance constraints.
    for (const auto& [a, b] : struts_) {
      auto ends = [&, a = a, b = b](int f) {
        return std::vector<Vector2d>{world(q_[f], a.body, a.s), world(q_[f], b.body, b.s)};
      };
      element(os, "polyline",
              "fill=\"none\" stroke=\"" + std::string(kGroundColour) +
                  "\" stroke-width=\"2\" stroke-dasharray=\"6 4\"",
              {{"points", [&, ends](int f) { return points_at(f, ends); }}});
    }

    // Bodies: a bar through two points, a plate through more.
    for (int b = 0; b < static_cast<int>(body_points_.size()); ++b) {
      const auto& pts = body_points_[b];
      auto shape = [&, b](int f) {
        std::vector<Vector2d> out;
        for (const auto& s : body_points_[b]) out.push_back(world(q_[f], b, s));
        return out;
      };
      os << "  <!-- body " << escape(m.bodies[b].name) << " -->\n";
      if (pts.size() == 1) {
        element(os, "circle", "r=\"6\" fill=\"" + std::string(kLinkColour) + "\"",
                {{"cx", [&, shape](int f) { return num(px(shape(f)[0])[0]); }},
                 {"cy", [&, shape](int f) { return num(px(shape(f)[0])[1]); }}});
        continue;
      }
      const std::string tag = pts.size() == 2 ? "polyline" : "polygon";
      const std::string fill =
          pts.size() == 2 ? "fill=\"none\""
                          : "fill=\"" + std::string(kLinkColour) + "\" fill-opacity=\"0.2\"";
      element(os, tag,
              fill + " stroke=\"" + kLinkColour +
                  "\" stroke-width=\"8\" stroke-linejoin=\"round\" stroke-linecap=\"round\"",
              {{"points", [&, shape](int f) { return points_at(f, shape); }}});
    }

    // Pitch circles of gears and pinions, each with a radius along its body's x axis that
    // shows its rotation; the racks' pitch lines (dash-dot, as in a drawing).
    for (const auto& pc : pitch_circles_) {
      auto at = [&, pc](int f) { return px(world(q_[f], pc.centre.body, pc.centre.s)); };
      const std::string r = num(pc.radius * scale_);
      element(os, "circle",
              "r=\"" + r + "\" fill=\"none\" stroke=\"" + std::string(kGearColour) +
                  "\" stroke-width=\"2\"",
              {{"cx", [&, at](int f) { return num(at(f)[0]); }},
               {"cy", [&, at](int f) { return num(at(f)[1]); }}});
      auto mark = [&, pc](int f) {
        const double phi = pc.centre.body == kGround ? 0.0 : q_[f][3 * pc.centre.body + 2];
        const Vector2d c = world(q_[f], pc.centre.body, pc.centre.s);
        return std::vector<Vector2d>{c, c + rotate(phi, Vector2d(pc.radius, 0))};
      };
      element(os, "polyline",
              "fill=\"none\" stroke=\"" + std::string(kGearColour) +
                  "\" stroke-width=\"2\" stroke-linecap=\"round\"",
              {{"points", [&, mark](int f) { return points_at(f, mark); }}});
    }
    for (const auto& l : pitch_lines_) {
      auto ends = [&, l](int f) {
        return std::vector<Vector2d>{world(q_[f], l.guide, l.origin + l.travel_min * l.dir),
                                     world(q_[f], l.guide, l.origin + l.travel_max * l.dir)};
      };
      element(os, "polyline",
              "fill=\"none\" stroke=\"" + std::string(kGearColour) +
                  "\" stroke-width=\"2\" stroke-dasharray=\"12 4 2 4\"",
              {{"points", [&, ends](int f) { return points_at(f, ends); }}});
    }

    // Slot curves and cam profiles, sampled in their bodies' frames.
    for (const auto& c : curves_) {
      auto shape = [&, c](int f) {
        std::vector<Vector2d> pts;
        for (const auto& p : c.points) pts.push_back(world(q_[f], c.body, p));
        return pts;
      };
      element(os, "polyline",
              "fill=\"none\" stroke=\"" + std::string(kGearColour) +
                  "\" stroke-width=\"2\" stroke-linejoin=\"round\"",
              {{"points", [&, shape](int f) { return points_at(f, shape); }}});
    }

    // Slider blocks, along their guide.
    for (const auto& sl : sliders_) {
      auto block = [&, sl](int f) {
        const Vector2d c = world(q_[f], sl.point.body, sl.point.s);
        const double phi = sl.guide == kGround ? 0.0 : q_[f][3 * sl.guide + 2];
        const Vector2d d = rotate(phi, sl.dir) * (15 / scale_), n = Vector2d(-d[1], d[0]) * 0.55;
        return std::vector<Vector2d>{c - d - n, c + d - n, c + d + n, c - d + n};
      };
      element(os, "polygon",
              "fill=\"" + std::string(kSliderFill) + "\" stroke=\"" + kPinStroke +
                  "\" stroke-width=\"1.5\"",
              {{"points", [&, block](int f) { return points_at(f, block); }}});
    }

    // Pins of revolute joints.
    for (const auto& pin : pins_) {
      auto at = [&, pin](int f) { return px(world(q_[f], pin.body, pin.s)); };
      element(
          os, "circle",
          "r=\"5\" fill=\"#ffffff\" stroke=\"" + std::string(kPinStroke) + "\" stroke-width=\"2\"",
          {{"cx", [&, at](int f) { return num(at(f)[0]); }},
           {"cy", [&, at](int f) { return num(at(f)[1]); }}});
    }

    // Welds of fixed joints: a filled square where the bodies are joined.
    for (const auto& w : welds_) {
      auto square = [&, w](int f) {
        const Vector2d c = world(q_[f], w.body, w.s);
        const double h = 5 / scale_;
        return std::vector<Vector2d>{c + Vector2d(-h, -h), c + Vector2d(h, -h), c + Vector2d(h, h),
                                     c + Vector2d(-h, h)};
      };
      element(os, "polygon",
              "fill=\"" + std::string(kPinStroke) + "\" stroke=\"" + kPinStroke +
                  "\" stroke-width=\"1\"",
              {{"points", [&, square](int f) { return points_at(f, square); }}});
    }

    // Reaction forces: an arrow from each joint's point, to one scale for the whole picture.
    if (options_.forces) {
      // Of the picture as written (whole pixels).
      const double longest =
          0.25 * std::min(std::round(width_), std::round(height_) - kTitle);
      const double per_force = largest_force_ > 0 ? longest / largest_force_ : 0;
      for (const auto& r : reactions_) {
        // In pixels: the tail at the point, the head along the force (y down).
        auto arrow = [&, r](int f) {
          const Vector2d tail = px(world(q_[f], r.at.body, r.at.s));
          const Vector2d force(forces_[f][r.column], -forces_[f][r.column + 1]);
          const Vector2d tip = tail + per_force * force;
          const double length = (tip - tail).norm();
          const Vector2d d = length > 0 ? Vector2d((tip - tail) / length) : Vector2d(1, 0);
          const Vector2d n(-d[1], d[0]);
          const double head = std::min(9.0, 0.4 * length);
          const Vector2d base = tip - head * d;
          return std::vector<Vector2d>{tail, base, base + 0.45 * head * n, tip,
                                       base - 0.45 * head * n, base};
        };
        const auto pixels = [&, arrow](int f) {
          std::string s;
          for (const auto& p : arrow(f)) s += (s.empty() ? "" : " ") + num(p[0]) + "," + num(p[1]);
          return s;
        };
        os << "  <!-- reaction of " << escape(r.item) << " -->\n";
        element(os, "polyline",
                "fill=\"" + std::string(kForceColour) + "\" stroke=\"" + kForceColour +
                    "\" stroke-width=\"2.5\" stroke-linejoin=\"round\"",
                {{"points", pixels}});
      }
      os << "  <text x=\"" << num(kMargin) << "\" y=\"" << num(height_ - 8)
         << "\" font-family=\"sans-serif\" font-size=\"12\" fill=\"" << kForceColour
         << "\">reactions: the longest arrow is "
         << escape(format_number(largest_force_, NumberStyle::kShort))
         << "</text>\n";
    }

    // Named points and their labels.
    for (std::size_t k = 0; k < named_.size(); ++k) {
      auto at = [&, n = named_[k]](int f) { return px(world(q_[f], n.body, n.s)); };
      element(os, "circle", "r=\"3.5\" fill=\"" + std::string(kPointColour) + "\"",
              {{"cx", [&, at](int f) { return num(at(f)[0]); }},
               {"cy", [&, at](int f) { return num(at(f)[1]); }}});
      element(os, "text",
              "font-family=\"sans-serif\" font-size=\"13\" fill=\"" + std::string(kPointColour) +
                  "\" stroke=\"#ffffff\" stroke-width=\"3\" paint-order=\"stroke\"",
              {{"x", [&, at](int f) { return num(at(f)[0] + 6); }},
               {"y", [&, at](int f) { return num(at(f)[1] - 6); }}},
              escape(m.points[k].name));
    }
    os << "</svg>\n";
    return os.str();
  }

  static constexpr double kMargin = 40;  // pixels around the extents (ground marks, labels)
  static constexpr double kTitle = 24;   // pixels above for the title line

  const CompiledModel& model_;
  AnimateOptions options_;
  std::vector<Eigen::VectorXd> q_;
  std::vector<double> t_;
  std::vector<std::vector<Vector2d>> body_points_;
  std::vector<Attach> pins_, named_;
  std::vector<Vector2d> ground_pivots_;
  std::vector<Slider> sliders_;
  std::vector<std::pair<Attach, Attach>> struts_;
  std::vector<Sketch::Circle> pitch_circles_;
  std::vector<Slider> pitch_lines_;  // travel: of the pinion's centre along the line
  std::vector<Attach> welds_;
  std::vector<Sketch::Curve> curves_;
  // Each drawing constraint with the Sketch's element counts after it (AnimateDrawing's *_by).
  std::vector<std::pair<const Constraint*, std::array<std::size_t, 7>>> drawn_;
  // With options_.forces.
  struct Reaction {
    Attach at;
    int column;
    std::string item;
  };
  ForceModel force_model_;
  std::vector<std::vector<double>> forces_;
  std::vector<Reaction> reactions_;
  double largest_force_ = 0;
  double scale_ = 1, x0_ = 0, y0_ = 0, width_ = 0, height_ = 0, duration_ = 1;
};

}  // namespace

AnimateDrawing animate_drawing(const CompiledModel& model, std::vector<Eigen::VectorXd> q,
                               int width) {
  return Picture(model, std::move(q), width).drawing();
}

std::string animate_svg(const CompiledModel& model, const AnimateOptions& options) {
  return Picture(model, options).render();
}

}  // namespace kinegen::codegen

// Picture (picture.hpp): the motion solved over the grid, what each constraint type draws,
// where the bodies' outlines attach, and the view fitted to it all.
#include "picture.hpp"

namespace kinegen::codegen {

namespace io_detail {

void Picture::solve() {
  const TimeGrid& g = options_.grid;
  if (g.steps < 0) throw UsageError("--steps must be 0 or more");
  if (!std::isfinite(g.t0) || !std::isfinite(g.t1))
    throw UsageError("--t0 and --t1 must be finite");
  if (options_.frame > g.steps)
    throw UsageError("--frame " + std::to_string(options_.frame) + " is beyond the last step (" +
                     std::to_string(g.steps) + ")");
  if (options_.width < 50 || options_.width > 20000)
    throw UsageError("--width must be between 50 and 20000 pixels");
  // Every frame's q (and forces) is kept, and the SVG animates each drawn value over them.
  const Mechanism& m = model_.mechanism();
  require_kept_rows("animate", g.steps + 1LL,
                    static_cast<std::size_t>(m.nq()) + 2 * m.points.size() +
                        (options_.forces ? force_columns(m).size() : 0));
  if (!options_.positions.empty()) {  // given (a mode): drawn as they are, at the grid's times
    q_ = options_.positions;
    for (std::size_t k = 0; k < q_.size(); ++k)
      t_.push_back(g.t0 + (g.t1 - g.t0) * static_cast<double>(k) /
                              std::max<double>(1.0, static_cast<double>(q_.size() - 1)));
    return;
  }
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
void Picture::collect_reactions() {
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

void Picture::collect() {
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
                       sketch.pitch_circles.size(), sketch.pitch_lines.size(), sketch.welds.size(),
                       sketch.curves.size()}});
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
Vector2d Picture::curve_point(const Constraint& c, const std::string& key, double u) const {
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
std::pair<double, double> Picture::curve_range(int k) const {
  const int index = model_.mechanism().coordinate_index(k);
  double lo = q_[0][index], hi = lo;
  for (const auto& q : q_) lo = std::min(lo, q[index]), hi = std::max(hi, q[index]);
  if (model_.mechanism().coordinates[k].kind == CoordinateKind::kAngle) {
    const double mid = (lo + hi) / 2;
    return {mid - kPi, mid + kPi};
  }
  const double margin =
      std::max(0.25 * (hi - lo), 0.05 * model_.symbolic().coordinate_scales[index]);
  return {lo - margin, hi + margin};
}

// A point that keeps its place in a body's frame over the whole analysis belongs to that
// body's drawing, whichever body the file put it on: this draws mechanisms written with
// `expression` constraints, where the joints are not named.
void Picture::infer_attachments() {
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
void Picture::fit() {
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

}  // namespace io_detail

std::string animate_svg(const CompiledModel& model, const AnimateOptions& options) {
  return io_detail::Picture(model, options).render();
}

}  // namespace kinegen::codegen

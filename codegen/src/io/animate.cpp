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
  collect_loads();
}

void Picture::collect_loads() {
  const Mechanism& m = model_.mechanism();
  // A value that does not change (a number, a parameter's expression); false for one that
  // reads the time, the state or an input.
  const auto constant = [&](const Expr& e, const std::string& item, double& v) {
    if (e.text == "input") return false;
    try {
      v = number(e, item);
    } catch (const std::exception&) {
      return false;
    }
    return std::isfinite(v);
  };
  const auto point = [&](const Vec2& v, const std::string& item, Vector2d& out) {
    return constant(v.x, item, out[0]) && constant(v.y, item, out[1]);
  };
  for (const Load& l : m.forces.loads) {
    const std::string& name = l.item;  // with its name: "forces[2] 'push' (force)"
    double k = 1, c = 1, fx = 1, fy = 1;
    Vector2d si, sj, s;
    switch (l.kind) {
      case Load::Kind::kSpringDamper:
      case Load::Kind::kRotationalSpringDamper: {
        AnimateDrawing::Spring sp;
        sp.name = name;
        const bool stiff = !(constant(l.stiffness, l.item, k) && k == 0);
        sp.damper = !(constant(l.damping, l.item, c) && c == 0);
        sp.spring = stiff || !sp.damper;
        if (l.kind == Load::Kind::kSpringDamper) {
          if (!point(l.si, l.item, si) || !point(l.sj, l.item, sj)) continue;
          sp.a = {l.i, si};
          sp.b = {l.j, sj};
        } else {
          // At the pin that joins its two bodies, else at body j's origin (i's if j is ground).
          sp.rotational = true;
          sp.a = {l.j != kGround ? l.j : l.i, Vector2d::Zero()};
          for (const Constraint& j : m.joints) {
            if (std::string(j.kind->name) != "revolute") continue;
            if (!((j.i == l.i && j.j == l.j) || (j.i == l.j && j.j == l.i))) continue;
            const int on = j.j != kGround ? j.j : j.i;
            Vector2d at;
            if (point(j.vector(on == j.j ? "sj" : "si"), j.item, at)) sp.a = {on, at};
            break;
          }
          sp.b = sp.a;
        }
        springs_.push_back(sp);
        break;
      }
      case Load::Kind::kForce: {
        if (!point(l.s, l.item, s)) continue;
        const bool cx = constant(l.f.x, l.item, fx), cy = constant(l.f.y, l.item, fy);
        if (cx && cy) {  // one arrow along the force (none for a zero force)
          if (fx != 0 || fy != 0)
            loads_.push_back({{l.body, s}, Vector2d(fx, fy).normalized(), false, name});
          continue;
        }
        // Along each component's axis that is not a constant 0: the positive direction where
        // it varies, its sign where it is constant.
        if (!(cx && fx == 0))
          loads_.push_back({{l.body, s}, Vector2d(cx && fx < 0 ? -1 : 1, 0), false, name});
        if (!(cy && fy == 0))
          loads_.push_back({{l.body, s}, Vector2d(0, cy && fy < 0 ? -1 : 1), false, name});
        break;
      }
      case Load::Kind::kTorque: {
        double v = 1;
        const bool cv = constant(l.value, l.item, v);
        if (cv && v == 0) continue;
        loads_.push_back(
            {{l.body, Vector2d::Zero()}, Vector2d(cv && v < 0 ? -1 : 1, 0), true, name});
        break;
      }
    }
  }
}

// A curve key of `c` at u: the curve reads only its own coordinate (checked when
// it was derived), so every extra coordinate is set to u.
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
  const auto& masses = model_.mechanism().forces.bodies;
  for (std::size_t k = 0; k < body_points_.size(); ++k) {
    auto& pts = body_points_[k];
    // Fewer than two points make no bar: the centre of mass, then the frame's origin, are the
    // body's other landmarks. A body left with one point is drawn as a disc (draw_bodies).
    if (pts.size() < 2 && k < masses.size()) {
      const std::string item = "bodies[" + std::to_string(k) + "] com";
      try {
        const Vector2d com(number(masses[k].com.x, item), number(masses[k].com.y, item));
        if (com.allFinite()) add_unique(pts, com, tol);
      } catch (const std::exception&) {  // not a number here: the frame's origin draws it
      }
    }
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
    for (const auto& sp : springs_) {
      box.extend(world(q, sp.a.body, sp.a.s));
      box.extend(world(q, sp.b.body, sp.b.s));
    }
    for (const auto& l : loads_) box.extend(world(q, l.at.body, l.at.s));
  }
  for (const auto& g : ground_pivots_) box.extend(g);
  // Everything drawn at (nearly) one place, as a flywheel on its pivot: a view a quarter of the
  // length scale across, not one that magnifies rounding (the pixels' symbols stay their size).
  const double least = 0.25 * model_.symbolic().length_scale;
  if (box.sizes().maxCoeff() < least) {
    const Vector2d centre = box.center();
    box.extend(centre - Vector2d(least, least) / 2);
    box.extend(centre + Vector2d(least, least) / 2);
  }
  const Vector2d size = box.sizes().cwiseMax(1e-9 * model_.symbolic().length_scale);
  const double w = options_.width;
  // At most kMaxAspect of the width tall, title included: a tall mechanism fits a screen beside
  // the page's controls.
  const double inner = std::max(10.0, w - 2 * kMargin);
  const double inner_height = std::max(10.0, kMaxAspect * w - 2 * kMargin - kTitle);
  scale_ = std::min(inner / size[0], inner_height / size[1]);
  width_ = size[0] * scale_ + 2 * kMargin;
  height_ = size[1] * scale_ + 2 * kMargin + kTitle;
  x0_ = kMargin - scale_ * box.min()[0];
  y0_ = kMargin + kTitle + scale_ * box.max()[1];
  // Wide enough for the title: a narrow picture is widened, the mechanism in its middle.
  const double title = std::min(w, 2 * kMargin + 8.0 * static_cast<double>(title_chars()));
  if (width_ < title) {
    x0_ += (title - width_) / 2;
    width_ = title;
  }
}

std::size_t Picture::title_chars() const {
  // The page's and animate's titles: the name and the time ("   t = -1.234e-05 .. 6.283").
  return std::max(model_.mechanism().name.size() + 30, options_.title.size());
}

}  // namespace io_detail

std::string animate_svg(const CompiledModel& model, const AnimateOptions& options) {
  return io_detail::Picture(model, options).render();
}

}  // namespace kinegen::codegen

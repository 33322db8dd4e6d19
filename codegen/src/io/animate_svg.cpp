// Picture (picture.hpp): the SVG text: the title, then each kind of element (paths, guides,
// pivots, struts, bodies, gears, curves, sliders, pins, welds, reactions, points), animated
// over the frames or still.
#include "picture.hpp"

namespace kinegen::codegen::io_detail {

namespace {
constexpr double kZigWidth = 5;    // a zig-zag's and a dashpot's half width
constexpr double kSideBySide = 8;  // a spring and a damper in parallel: each this far aside
constexpr int kZigs = 10;
constexpr double kArrowLength = 40, kHead = 9;
constexpr double kTorqueRadius = 16;
}  // namespace

Strokes spring_strokes(const Vector2d& a, const Vector2d& b, bool spring, bool damper) {
  const Vector2d ab = b - a;
  const double length = ab.norm();
  const Vector2d d = length > 1e-9 ? Vector2d(ab / length) : Vector2d(1, 0);
  const Vector2d n(-d[1], d[0]);
  const auto at = [&](double u, double off) -> Vector2d { return a + u * ab + off * n; };
  Strokes out;
  const auto zigzag = [&](double u0, double u1, double off) {
    std::vector<Vector2d> z{at(u0, off)};
    for (int k = 1; k < kZigs; ++k)
      z.push_back(at(u0 + (u1 - u0) * k / kZigs, off + (k % 2 ? kZigWidth : -kZigWidth)));
    z.push_back(at(u1, off));
    return z;
  };
  const auto dashpot = [&](double u0, double u1, double off) {
    const double c0 = u0 + 0.3 * (u1 - u0), c1 = u0 + 0.7 * (u1 - u0), p = u0 + 0.55 * (u1 - u0);
    out.push_back({at(u0, off), at(c0, off)});
    out.push_back({at(c1, off + kZigWidth), at(c0, off + kZigWidth), at(c0, off - kZigWidth),
                   at(c1, off - kZigWidth)});
    out.push_back({at(p, off + 0.6 * kZigWidth), at(p, off - 0.6 * kZigWidth)});
    out.push_back({at(p, off), at(u1, off)});
  };
  if (spring && damper) {
    out.push_back({a, at(0.15, 0)});
    out.push_back({at(0.15, kSideBySide), at(0.15, -kSideBySide)});
    out.push_back(zigzag(0.15, 0.85, kSideBySide));
    dashpot(0.15, 0.85, -kSideBySide);
    out.push_back({at(0.85, kSideBySide), at(0.85, -kSideBySide)});
    out.push_back({at(0.85, 0), b});
  } else if (damper) {
    dashpot(0, 1, 0);
  } else {
    std::vector<Vector2d> z = zigzag(0.2, 0.8, 0);
    z.insert(z.begin(), a);
    z.push_back(b);
    out.push_back(z);
  }
  return out;
}

Strokes coil_strokes(const Vector2d& centre) {
  std::vector<Vector2d> spiral;
  for (int k = 0; k <= 40; ++k) {  // two and a half turns, from 3 to 13 pixels
    const double u = k / 40.0, angle = 5 * kPi * u;
    spiral.push_back(centre + (3 + 10 * u) * Vector2d(std::cos(angle), -std::sin(angle)));
  }
  return {spiral};
}

Strokes force_strokes(const Vector2d& at, const Vector2d& dir) {
  const Vector2d d = Vector2d(dir[0], -dir[1]).normalized(), n(-d[1], d[0]);
  const Vector2d base = at - kHead * d;
  return {{at - kArrowLength * d, at}, {base + 0.45 * kHead * n, at, base - 0.45 * kHead * n}};
}

Strokes torque_strokes(const Vector2d& centre, double sign) {
  std::vector<Vector2d> arc;
  for (int k = 0; k <= 24; ++k) {  // from -60 to 210 degrees, counter-clockwise (y up)
    const double u = sign > 0 ? k / 24.0 : 1 - k / 24.0, angle = kPi * (-1.0 / 3 + 1.5 * u);
    arc.push_back(centre + kTorqueRadius * Vector2d(std::cos(angle), -std::sin(angle)));
  }
  const Vector2d end = arc.back(), t = (end - arc[arc.size() - 2]).normalized(), n(-t[1], t[0]);
  const Vector2d base = end - kHead * t;
  return {arc, {base + 0.45 * kHead * n, end, base - 0.45 * kHead * n}};
}

std::string path_data(const Strokes& strokes) {
  std::string d;
  for (const auto& stroke : strokes)
    for (std::size_t k = 0; k < stroke.size(); ++k)
      d += (d.empty() ? "" : " ") + std::string(k ? "L" : "M") + num(stroke[k][0]) + "," +
           num(stroke[k][1]);
  return d;
}

void Picture::element(std::ostringstream& os, const std::string& tag, const std::string& fixed,
                      const std::vector<Animated>& animated, const std::string& content) {
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

std::string Picture::points_at(int f,
                               const std::function<std::vector<Vector2d>(int)>& shape) const {
  std::string s;
  for (const auto& p : shape(f)) s += (s.empty() ? "" : " ") + num(px(p)[0]) + "," + num(px(p)[1]);
  return s;
}

std::string Picture::emit() {
  const TimeGrid& g = options_.grid;
  duration_ = options_.duration > 0 ? options_.duration : (g.t1 - g.t0 > 0 ? g.t1 - g.t0 : 4.0);
  const Mechanism& m = model_.mechanism();
  std::ostringstream os;
  os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
     << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << std::lround(width_)
     << "\" height=\"" << std::lround(height_) << "\" viewBox=\"0 0 " << std::lround(width_) << " "
     << std::lround(height_) << "\" data-kinegen-scale=\"" << format_number(scale_)
     << "\" data-kinegen-x0=\"" << format_number(x0_) << "\" data-kinegen-y0=\""
     << format_number(y0_) << "\">\n";
  os << "  <!-- Generated by kinegen "
     << "from " << escape(m.source) << ": "
     << (still() ? "frame " + std::to_string(options_.frame) : std::to_string(frames()) + " frames")
     << " of t = " << format_number(g.t0) << " .. " << format_number(g.t1) << " -->\n";
  os << "  <rect width=\"100%\" height=\"100%\" fill=\"" << kBackgroundColour << "\"/>\n";
  const auto short_number = [](double v) { return format_number(v, NumberStyle::kShort); };
  const std::string title =
      !options_.title.empty()
          ? options_.title
          : m.name + (still() ? "   t = " + short_number(t_[options_.frame])
                              : "   t = " + short_number(g.t0) + " .. " + short_number(g.t1));
  os << "  <text x=\"" << num(kMargin) << "\" y=\"" << num(kTitle * 0.7)
     << "\" font-family=\"sans-serif\" font-size=\"14\" fill=\"#333333\">" << escape(title)
     << "</text>\n";

  draw_paths(os);
  draw_guides(os);
  draw_ground_pivots(os);
  draw_struts(os);
  draw_springs(os);
  draw_bodies(os);
  draw_gears(os);
  draw_curves(os);
  draw_sliders(os);
  draw_pins(os);
  draw_welds(os);
  draw_reactions(os);
  draw_loads(os);
  draw_points(os);
  os << "</svg>\n";
  return os.str();
}

// Traced paths of the named points (the whole analysis, also in a still frame).
void Picture::draw_paths(std::ostringstream& os) {
  for (const auto& n : named_) {
    std::string pts;
    for (const auto& q : q_) {
      const Vector2d p = px(world(q, n.body, n.s));
      pts += (pts.empty() ? "" : " ") + num(p[0]) + "," + num(p[1]);
    }
    os << "  <polyline fill=\"none\" stroke=\"" << kPathColour
       << "\" stroke-width=\"1.5\" stroke-dasharray=\"4 3\" points=\"" << pts << "\"/>\n";
  }
}

// Guides: fixed ones once; those on moving bodies (slots) move with them.
void Picture::draw_guides(std::ostringstream& os) {
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
      element(os, "polyline", style, {{"points", [&, ends](int f) { return points_at(f, ends); }}});
    }
  }
}

// Ground pivots: a triangle with hatching under the pin.
void Picture::draw_ground_pivots(std::ostringstream& os) {
  for (const auto& g0 : ground_pivots_) {
    const Vector2d p = px(g0);
    os << "  <polygon fill=\"#dddddd\" stroke=\"" << kGroundColour
       << "\" stroke-width=\"1.5\" points=\"" << num(p[0]) << "," << num(p[1]) << " "
       << num(p[0] - 10) << "," << num(p[1] + 16) << " " << num(p[0] + 10) << "," << num(p[1] + 16)
       << "\"/>\n";
    for (int k = 0; k < 5; ++k) {
      const double x = p[0] - 12 + 6 * k;
      os << "  <line x1=\"" << num(x) << "\" y1=\"" << num(p[1] + 16) << "\" x2=\"" << num(x - 5)
         << "\" y2=\"" << num(p[1] + 22) << "\" stroke=\"" << kGroundColour
         << "\" stroke-width=\"1\"/>\n";
    }
  }
}

// Struts of distance constraints.
void Picture::draw_struts(std::ostringstream& os) {
  for (const auto& [a, b] : struts_) {
    auto ends = [&, a = a, b = b](int f) {
      return std::vector<Vector2d>{world(q_[f], a.body, a.s), world(q_[f], b.body, b.s)};
    };
    element(os, "polyline",
            "fill=\"none\" stroke=\"" + std::string(kGroundColour) +
                "\" stroke-width=\"2\" stroke-dasharray=\"6 4\"",
            {{"points", [&, ends](int f) { return points_at(f, ends); }}});
  }
}

// Bodies: a bar through two points, a plate through more.
void Picture::draw_bodies(std::ostringstream& os) {
  const Mechanism& m = model_.mechanism();
  for (int b = 0; b < static_cast<int>(body_points_.size()); ++b) {
    const auto& pts = body_points_[b];
    auto shape = [&, b](int f) {
      std::vector<Vector2d> out;
      for (const auto& s : body_points_[b]) out.push_back(world(q_[f], b, s));
      return out;
    };
    os << "  <!-- body " << escape(m.bodies[b].name) << " -->\n";
    if (pts.size() == 1) {
      // A disc about its one point, wider than a pin, and a radius along its x axis that
      // shows its rotation (a flywheel on its pivot, a block at its slider).
      element(os, "circle",
              "r=\"" + num(kBodyDiscRadius) + "\" fill=\"" + std::string(kLinkColour) +
                  "\" fill-opacity=\"0.35\" stroke=\"" + kLinkColour + "\" stroke-width=\"3\"",
              {{"cx", [&, shape](int f) { return num(px(shape(f)[0])[0]); }},
               {"cy", [&, shape](int f) { return num(px(shape(f)[0])[1]); }}});
      auto mark = [&, b](int f) {
        const Vector2d c = world(q_[f], b, body_points_[b][0]);
        return std::vector<Vector2d>{
            c, c + rotate(q_[f][3 * b + 2], Vector2d(kBodyDiscRadius / scale_, 0))};
      };
      element(os, "polyline",
              "fill=\"none\" stroke=\"" + std::string(kLinkColour) +
                  "\" stroke-width=\"3\" stroke-linecap=\"round\"",
              {{"points", [&, mark](int f) { return points_at(f, mark); }}});
      continue;
    }
    const std::string tag = pts.size() == 2 ? "polyline" : "polygon";
    const std::string fill = pts.size() == 2
                                 ? "fill=\"none\""
                                 : "fill=\"" + std::string(kLinkColour) + "\" fill-opacity=\"0.2\"";
    element(os, tag,
            fill + " stroke=\"" + kLinkColour +
                "\" stroke-width=\"8\" stroke-linejoin=\"round\" stroke-linecap=\"round\"",
            {{"points", [&, shape](int f) { return points_at(f, shape); }}});
  }
}

// Pitch circles of gears and pinions, each with a radius along its body's x axis that
// shows its rotation; the racks' pitch lines (dash-dot, as in a drawing).
void Picture::draw_gears(std::ostringstream& os) {
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
}

// Slot curves and cam profiles, sampled in their bodies' frames.
void Picture::draw_curves(std::ostringstream& os) {
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
}

// Slider blocks, along their guide.
void Picture::draw_sliders(std::ostringstream& os) {
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
}

// Pins of revolute joints.
void Picture::draw_pins(std::ostringstream& os) {
  for (const auto& pin : pins_) {
    auto at = [&, pin](int f) { return px(world(q_[f], pin.body, pin.s)); };
    element(
        os, "circle",
        "r=\"5\" fill=\"#ffffff\" stroke=\"" + std::string(kPinStroke) + "\" stroke-width=\"2\"",
        {{"cx", [&, at](int f) { return num(at(f)[0]); }},
         {"cy", [&, at](int f) { return num(at(f)[1]); }}});
  }
}

// Welds of fixed joints: a filled square where the bodies are joined.
void Picture::draw_welds(std::ostringstream& os) {
  for (const auto& w : welds_) {
    auto square = [&, w](int f) {
      const Vector2d c = world(q_[f], w.body, w.s);
      const double h = 5 / scale_;
      return std::vector<Vector2d>{c + Vector2d(-h, -h), c + Vector2d(h, -h), c + Vector2d(h, h),
                                   c + Vector2d(-h, h)};
    };
    element(
        os, "polygon",
        "fill=\"" + std::string(kPinStroke) + "\" stroke=\"" + kPinStroke + "\" stroke-width=\"1\"",
        {{"points", [&, square](int f) { return points_at(f, square); }}});
  }
}

// Reaction forces: an arrow from each joint's point, to one scale for the whole picture.
void Picture::draw_reactions(std::ostringstream& os) {
  if (options_.forces) {
    // Of the picture as written (whole pixels).
    const double longest = 0.25 * std::min(std::round(width_), std::round(height_) - kTitle);
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
        return std::vector<Vector2d>{
            tail, base, base + 0.45 * head * n, tip, base - 0.45 * head * n, base};
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
       << escape(format_number(largest_force_, NumberStyle::kShort)) << "</text>\n";
  }
}

// Springs and dampers: a zig-zag, a dashpot, both side by side; a coil for a rotational one
// (dashed when it only damps).
void Picture::draw_springs(std::ostringstream& os) {
  for (const auto& sp : springs_) {
    auto d = [&, sp](int f) {
      const Vector2d a = px(world(q_[f], sp.a.body, sp.a.s));
      if (sp.rotational) return path_data(coil_strokes(a));
      return path_data(
          spring_strokes(a, px(world(q_[f], sp.b.body, sp.b.s)), sp.spring, sp.damper));
    };
    os << "  <!-- " << escape(sp.name) << " -->\n";
    element(os, "path",
            "fill=\"none\" stroke=\"" + std::string(kSpringColour) +
                "\" stroke-width=\"1.8\" stroke-linejoin=\"round\"" +
                (sp.rotational && !sp.spring ? " stroke-dasharray=\"3 2\"" : ""),
            {{"d", d}});
  }
}

// Applied forces and torques: arrows of one length (where each acts and which way, not how
// much; a varying force: the positive direction of each component).
void Picture::draw_loads(std::ostringstream& os) {
  for (const auto& l : loads_) {
    auto d = [&, l](int f) {
      const Vector2d at = px(world(q_[f], l.at.body, l.at.s));
      return path_data(l.torque ? torque_strokes(at, l.dir[0]) : force_strokes(at, l.dir));
    };
    os << "  <!-- " << escape(l.name) << " -->\n";
    element(os, "path",
            "fill=\"none\" stroke=\"" + std::string(kLoadColour) +
                "\" stroke-width=\"2.5\" stroke-linejoin=\"round\" stroke-linecap=\"round\"",
            {{"d", d}});
  }
}

// Named points and their labels.
void Picture::draw_points(std::ostringstream& os) {
  const Mechanism& m = model_.mechanism();
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
}

}  // namespace kinegen::codegen::io_detail

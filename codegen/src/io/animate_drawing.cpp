// Picture::drawing (picture.hpp): animate's drawing as numbers, for `kinegen view`'s page,
// which moves the same pieces to each row rather than drawing the mechanism a second time.
#include "picture.hpp"

namespace kinegen::codegen {

namespace io_detail {

AnimateDrawing Picture::drawing() {
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
  d.springs = springs_;
  d.loads = loads_;
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
               {"gear", kGearColour},   {"spring", kSpringColour},
               {"load", kLoadColour}};
  return d;
}

}  // namespace io_detail

AnimateDrawing animate_drawing(const CompiledModel& model, std::vector<Eigen::VectorXd> q,
                               int width) {
  return io_detail::Picture(model, std::move(q), width).drawing();
}

}  // namespace kinegen::codegen

// SuspensionRows (suspension.hpp): the design position's solve and the motion ratios.
#include "kinegen/codegen/analysis/suspension.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

namespace {
// The order loader_suspension.cpp appends the outputs in: toe, camber, caster, kpi,
// contact_x, contact_y, contact_z, scrub_radius, trail, wheel_travel, track_change.
constexpr int kCaster = 2;
}  // namespace

SuspensionRows::SuspensionRows(const CompiledModel& model, const AnalysisOptions& options)
    : m_(model.mechanism()) {
  const Suspension& s = *m_.suspension;
  travel_ = s.first_output + SuspensionRows::kWheelTravel;
  track_ = s.first_output + SuspensionRows::kTrackChange;
  const double t = model.symbolic().design_t;
  AnalysisOptions quiet = options;
  quiet.warn = [](const std::string&) {};
  quiet.sensitivity = nullptr;
  quiet.forces = nullptr;
  bool solved = false;
  double caster0 = 0;
  try {
    run_analysis(
        model, {t, t, 0},
        [&](const StateRow& row) {
          caster0 = row.outputs[s.first_output + kCaster][0];
          travel0_ = row.outputs[travel_][0];
          track0_ = row.outputs[track_][0];
          solved = true;
        },
        quiet);
  } catch (const AnalysisError& e) {
    throw AnalysisError(std::string(e.what()) + " (solving the suspension's design position, " +
                        "design_t = " + format_number(t) + ")");
  }
  if (!solved) throw AnalysisError(m_.source + ": the suspension's design position was not solved");
  // caster = atan2(-k_x, k_z) is within a quarter turn exactly when k points up: steer_axis
  // given lower point first would turn caster and kpi by half a turn, silently.
  if (!(std::abs(caster0) < M_PI / 2))
    throw InputError(m_.source, "suspension", s.loc,
                     "steer_axis: '" + s.steer_upper + "' is not above '" + s.steer_lower +
                         "' at the design position (t = " + format_number(t) +
                         "); the upper point comes first");
}

std::vector<std::string> SuspensionRows::columns(const Mechanism& m) {
  std::vector<std::string> out;
  if (!m.suspension) return out;
  for (int k : m.suspension->springs) out.push_back(m.outputs[k].name + ".motion_ratio");
  return out;
}

void SuspensionRows::apply(StateRow& row) const {
  row.outputs[travel_][0] -= travel0_;
  row.outputs[track_][0] -= track0_;
}

std::vector<std::vector<double>> SuspensionRows::motion_ratios(
    const std::vector<StateRow>& rows) const {
  double largest = 0;
  for (const StateRow& r : rows) largest = std::max(largest, std::abs(r.outputs[travel_][1]));
  std::vector<std::vector<double>> out;
  for (const StateRow& r : rows) {
    const double rate = r.outputs[travel_][1];
    std::vector<double> ratios;
    for (int k : m_.suspension->springs)
      ratios.push_back(std::abs(rate) > 1e-9 * largest && largest > 0
                           ? -r.outputs[k][1] / rate
                           : std::numeric_limits<double>::quiet_NaN());
    out.push_back(std::move(ratios));
  }
  return out;
}

}  // namespace kinegen::codegen

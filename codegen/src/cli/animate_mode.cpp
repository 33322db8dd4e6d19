// `kinegen animate --mode K`: a vibration mode of `kinegen modes` drawn as a small oscillation
// about the equilibrium.
#include <cmath>
#include <limits>
#include <string>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/log.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "linear.hpp"

namespace kinegen::cli {

int run_animate_mode(const Common& c, kc::AnimateOptions options, const std::string& output,
                     int mode, double amplitude, const std::string& at) {
  if (options.forces) throw kc::UsageError("--forces does not apply to --mode");
  if (!std::isfinite(amplitude) || !(amplitude > 0))
    throw kc::UsageError("--amplitude must be a finite number above 0");
  if (options.grid.steps < 1) throw kc::UsageError("--steps must be at least 1");
  LinearSetup s = load_linear(c, "animate --mode", at, {"t", "z", "u"});
  // Every frame's positions are kept (and drawn into the SVG): the count is checked before
  // anything is computed or kept for it, as animate's analysis does (require_kept_rows).
  {
    const kc::Mechanism& mech = s.model->mechanism();
    const std::size_t per_frame = static_cast<std::size_t>(mech.nq()) + 2 * mech.points.size();
    const long long most = static_cast<long long>(kc::kMaxKeptValues / per_frame) - 1;
    if (options.grid.steps > most)
      throw kc::UsageError("--steps " + std::to_string(options.grid.steps) +
                           ": animate --mode keeps every frame in memory, at most " +
                           std::to_string(kc::kMaxKeptValues) + " numbers (" +
                           std::to_string(per_frame) + " a frame here); --steps " +
                           std::to_string(most) +
                           " is the most that fits (the default, 40, draws a smooth period)");
  }
  kc::OperatingPoint unset = s.at;
  unset.z.setConstant(std::numeric_limits<double>::quiet_NaN());
  const bool at_equilibrium =
      kc::parse_operating_point(s.model->mechanism(), at, {"t", "z", "u"}, unset)
          .z.array()
          .isNaN()
          .all();
  kc::OperatingPoint p = s.at;
  if (at_equilibrium) p = kc::find_equilibrium(*s.linearizer, s.at).at;
  const kc::ModalAnalysis a = kc::modal_analysis(*s.linearizer, p);
  if (mode < 1 || mode > static_cast<int>(a.modes.size()))
    throw kc::UsageError("--mode " + std::to_string(mode) + ": the mechanism has " +
                         std::to_string(a.modes.size()) + " mode" +
                         (a.modes.size() == 1 ? "" : "s") + " (1.." +
                         std::to_string(a.modes.size()) + ")");
  const kc::Mode& m = a.modes[mode - 1];
  const Eigen::VectorXd scales = s.linearizer->scales();
  const double size = (m.dz.array() / scales.array()).abs().maxCoeff();
  const double scale = amplitude / size;
  const int n = options.grid.steps;
  const double period = m.frequency > 0 ? 1 / m.frequency : 1.0;
  options.grid = {0, period, n};
  if (options.duration <= 0) options.duration = period;
  options.positions.clear();
  for (int k = 0; k <= n; ++k)
    options.positions.push_back(a.state.q + scale * std::sin(6.283185307179586 * k / n) * m.dq);
  options.title = s.model->mechanism().name + "   mode " + std::to_string(mode) + ": " +
                  (m.frequency > 0 ? kc::format_number(m.frequency, kc::NumberStyle::kShort) + " Hz"
                                   : std::string(kc::to_string(m.kind)));
  options.warn = warning_sink();
  const std::string svg = kc::animate_svg(*s.model, options);
  kc::OutputFile out(output);
  out.stream() << svg;
  out.commit();
  kc::Log::global().info("wrote " + output);
  return 0;
}

}  // namespace kinegen::cli

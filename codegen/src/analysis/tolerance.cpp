#include "kinegen/codegen/analysis/tolerance.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>

#include "kinegen/codegen/analysis/sensitivity.hpp"

namespace kinegen::codegen {

namespace {

// A uniform draw in [-1, 1) from the 53 high bits: the same on every platform, unlike
// std::uniform_real_distribution.
double symmetric_unit(std::mt19937_64& rng) {
  return 2 * (static_cast<double>(rng() >> 11) * 0x1.0p-53) - 1;
}

}  // namespace

std::vector<Tolerance> parse_tolerances(const std::vector<std::string>& items) {
  std::vector<Tolerance> out;
  std::set<std::string> seen;
  for (const auto& item : items) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      throw UsageError("--tol expects NAME=DELTA, got '" + item + "'");
    Tolerance t{item.substr(0, eq), 0};
    const std::string text = item.substr(eq + 1);
    char* end = nullptr;
    t.delta = std::strtod(text.c_str(), &end);
    if (end != text.c_str() + text.size())
      throw UsageError("--tol " + t.name + ": '" + text + "' is not a number");
    if (!std::isfinite(t.delta) || t.delta < 0)
      throw UsageError("--tol " + t.name + ": the tolerance must be a finite number >= 0, got '" +
                       text + "'");
    if (!seen.insert(t.name).second) throw UsageError("--tol " + t.name + ": given twice");
    out.push_back(t);
  }
  return out;
}

namespace {

// The samples' deviations of one row, summed without overflow: Welford's mean and sum of
// squared differences kept in units of `scale`, the largest |deviation| so far (which is the
// spread), so that deviations up to the largest double give a finite standard deviation.
struct ScaledMoments {
  Eigen::VectorXd scale, mean, m2;  // mean * scale and m2 * scale^2 are the true ones

  explicit ScaledMoments(Eigen::Index n)
      : scale(Eigen::VectorXd::Zero(n)), mean(Eigen::VectorXd::Zero(n)), m2(mean) {}

  // Sample number `count` (1, 2, ...).
  void add(const Eigen::VectorXd& dev, int count) {
    for (Eigen::Index k = 0; k < dev.size(); ++k) {
      const double a = std::abs(dev[k]);
      if (!std::isfinite(a)) {  // the deviation itself is beyond a double: so are both figures
        scale[k] = mean[k] = m2[k] = std::numeric_limits<double>::infinity();
        continue;
      }
      if (a > scale[k]) {  // a new unit: rescale what is summed so far (exact for powers of 2)
        const double ratio = scale[k] / a;
        mean[k] *= ratio;
        m2[k] *= ratio * ratio;
        scale[k] = a;
      }
      if (scale[k] == 0 || !std::isfinite(scale[k])) continue;
      const double x = dev[k] / scale[k];
      const double step = x - mean[k];
      mean[k] += step / count;
      m2[k] += step * (x - mean[k]);
    }
  }

  // The standard deviation of n samples: scale sqrt(m2 / (n - 1)), finite when the scale is.
  double std_dev(Eigen::Index k, int n) const {
    if (scale[k] == 0) return 0;
    return scale[k] * std::sqrt(std::max(m2[k], 0.0) / (n - 1));
  }
};

// Monte Carlo (options.monte_carlo samples, each parameter uniform in +-delta): the spread
// and standard deviation of each quantity's deviation from the `nominal` motion.
void monte_carlo(const CompiledModel& model, const ToleranceOptions& options,
                 const std::vector<std::string>& names, const std::vector<int>& index,
                 const Eigen::VectorXd& delta, const std::vector<Eigen::VectorXd>& nominal,
                 ToleranceResult& result) {
  const int n = options.monte_carlo;
  const Mechanism& m = model.mechanism();
  const std::size_t nqty = result.quantities.size();
  const std::size_t rows = result.t.size();
  std::vector<ScaledMoments> moments(rows, ScaledMoments(static_cast<Eigen::Index>(nqty)));
  std::mt19937_64 rng(options.seed);
  for (int s = 0; s < n; ++s) {
    std::vector<ParamOverride> overrides = options.overrides;
    std::string drawn;
    for (std::size_t k = 0; k < names.size(); ++k) {
      const double v = model.params()[index[k]] + delta[k] * symmetric_unit(rng);
      overrides.push_back({names[k], format_number(v)});
      drawn += (k ? ", " : "") + names[k] + " = " + format_number(v);
    }
    try {
      // Default BuildOptions (but a spatial file's) and AnalysisOptions: no progress, no
      // warnings; a sample is silent.
      BuildOptions build;
      build.spatial = model.build_options().spatial;
      const auto sample = CompiledModel::from_mechanism(m, overrides, build);
      const auto offsets = spatial_offsets(*sample);  // the sample's own points and vectors
      std::size_t r = 0;
      run_analysis(*sample, options.grid, [&](const StateRow& row) {
        // Deviations from the nominal.
        moments[r].add(position_values(m, offsets, row) - nominal[r], s + 1);
        ++r;
      });
    } catch (const AnalysisError& e) {
      // The file first, as in every message; then which sample, then what failed.
      std::string what = e.what();
      const std::string file = m.source + ": ";
      if (what.rfind(file, 0) == 0) what = what.substr(file.size());
      throw AnalysisError(file + "Monte Carlo sample " + std::to_string(s + 1) + " (" + drawn +
                          "): " + what);
    }
    if (options.progress) options.progress(s + 1, n);
  }
  for (std::size_t r = 0; r < rows; ++r) {
    const ScaledMoments& m = moments[r];
    result.mc_spread.emplace_back(m.scale.data(), m.scale.data() + nqty);
    std::vector<double> sd(nqty);
    for (std::size_t k = 0; k < nqty; ++k) sd[k] = m.std_dev(static_cast<Eigen::Index>(k), n);
    result.mc_std.push_back(std::move(sd));
  }
  result.samples = n;
}

}  // namespace

ToleranceResult tolerance_analysis(const CompiledModel& model, const ToleranceOptions& options) {
  if (options.tolerances.empty()) throw UsageError("tolerance needs at least one --tol NAME=DELTA");
  if (options.monte_carlo < 0 || options.monte_carlo == 1)
    throw UsageError(
        "--monte-carlo needs at least 2 samples (a spread and a standard "
        "deviation), got " +
        std::to_string(options.monte_carlo));
  if (options.grid.steps < 0) throw UsageError("--steps must be 0 or more");
  if (!std::isfinite(options.grid.t0) || !std::isfinite(options.grid.t1))
    throw UsageError("--t0 and --t1 must be finite");
  std::vector<std::string> names;
  std::vector<int> index;
  Eigen::VectorXd delta(options.tolerances.size());
  for (std::size_t k = 0; k < options.tolerances.size(); ++k) {
    names.push_back(options.tolerances[k].name);
    index.push_back(find_parameter(model, names.back(), "--tol"));
    delta[k] = options.tolerances[k].delta;
  }
  // The positions' sensitivities only: an output that reads velocities has none.
  const SensitivityModel sensitivity = build_sensitivity(model, names, /*outputs=*/false);

  ToleranceResult result;
  const Mechanism& m = model.mechanism();
  result.quantities = position_quantities(m);
  const std::size_t nqty = result.quantities.size();
  // Every row's figures are kept (the summary's largest values and their times, the CSV).
  require_kept_rows("tolerance", options.grid.steps + 1LL, nqty);

  std::vector<Eigen::VectorXd> nominal;
  AnalysisOptions analysis;
  analysis.sensitivity = &sensitivity;
  analysis.warn = options.warn;
  run_analysis(
      model, options.grid,
      [&](const StateRow& row) {
        // Eigen checks no sizes in a release build: a quantity list that missed a coordinate
        // would read and write past the rows.
        if (row.dq_dp.rows() + row.dpoints_dp.rows() != static_cast<Eigen::Index>(nqty))
          throw std::logic_error("tolerance: the quantities do not match the analysis rows");
        Eigen::MatrixXd d(nqty, names.size());
        d << row.dq_dp, row.dpoints_dp;
        const Eigen::MatrixXd scaled = d * delta.asDiagonal();  // dC/dp delta per parameter
        const Eigen::VectorXd worst = scaled.cwiseAbs().rowwise().sum();
        // Scaled by the largest term (stableNorm), so that squares beyond 1e308 do not
        // overflow; never above the worst case, as |x|_2 <= |x|_1 (a rounding could say
        // otherwise).
        const Eigen::VectorXd rss = scaled.rowwise().stableNorm().cwiseMin(worst);
        result.t.push_back(row.t);
        result.worst.emplace_back(worst.data(), worst.data() + nqty);
        result.rss.emplace_back(rss.data(), rss.data() + nqty);
        nominal.push_back(position_values(m, sensitivity.local3, row));
      },
      analysis);

  if (options.monte_carlo == 0) return result;
  monte_carlo(model, options, names, index, delta, nominal, result);
  return result;
}

std::string tolerance_summary(const ToleranceResult& result, const ToleranceOptions& options) {
  std::string out = "tolerances:";
  for (const auto& t : options.tolerances) out += " " + t.name + " +-" + format_number(t.delta);
  char buf[256];
  std::snprintf(buf, sizeof buf, "; %zu rows, t in [%g, %g]", result.t.size(), options.grid.t0,
                options.grid.t1);
  out += buf;
  if (result.samples > 0)
    out += "; Monte Carlo: " + std::to_string(result.samples) + " samples, seed " +
           std::to_string(options.seed) + ", uniform in [p - delta, p + delta]";
  out += "\n";
  std::size_t width = 8;
  for (const auto& q : result.quantities) width = std::max(width, q.size());
  const int w = static_cast<int>(width);
  std::snprintf(buf, sizeof buf, "%-*s %12s %10s %12s %10s", w, "quantity", "worst case", "at t",
                "rss", "at t");
  out += buf;
  if (result.samples > 0) {
    std::snprintf(buf, sizeof buf, " %12s %10s %12s %10s", "mc spread", "at t", "mc std", "at t");
    out += buf;
  }
  out += "\n";
  // The largest value over the motion and its (first) time.
  const auto largest = [&](const std::vector<std::vector<double>>& table, std::size_t q) {
    std::size_t at = 0;
    for (std::size_t r = 1; r < table.size(); ++r)
      if (table[r][q] > table[at][q]) at = r;
    return std::pair<double, double>{table[at][q], result.t[at]};
  };
  for (std::size_t q = 0; q < result.quantities.size(); ++q) {
    const auto [worst, t_worst] = largest(result.worst, q);
    const auto [rss, t_rss] = largest(result.rss, q);
    std::snprintf(buf, sizeof buf, "%-*s %12.6g %10.6g %12.6g %10.6g", w,
                  result.quantities[q].c_str(), worst, t_worst, rss, t_rss);
    out += buf;
    if (result.samples > 0) {
      const auto [spread, t_spread] = largest(result.mc_spread, q);
      const auto [sd, t_sd] = largest(result.mc_std, q);
      std::snprintf(buf, sizeof buf, " %12.6g %10.6g %12.6g %10.6g", spread, t_spread, sd, t_sd);
      out += buf;
    }
    out += "\n";
  }
  out +=
      "(lengths in the file's unit, angles in rad; worst case = sum |dC/dp| delta, rss = "
      "sqrt(sum (dC/dp delta)^2)";
  if (result.samples > 0)
    out += "; for small tolerances mc spread <= worst case and mc std ~ rss / sqrt(3)";
  return out + ")\n";
}

std::string tolerance_csv(const ToleranceResult& result) {
  std::string s = "t";
  for (const auto& q : result.quantities) {
    s += "," + q + ".worst," + q + ".rss";
    if (result.samples > 0) s += "," + q + ".mc_spread," + q + ".mc_std";
  }
  s += "\n";
  for (std::size_t r = 0; r < result.t.size(); ++r) {
    s += format_number(result.t[r]);
    for (std::size_t q = 0; q < result.quantities.size(); ++q) {
      s += "," + format_number(result.worst[r][q]) + "," + format_number(result.rss[r][q]);
      if (result.samples > 0)
        s += "," + format_number(result.mc_spread[r][q]) + "," + format_number(result.mc_std[r][q]);
    }
    s += "\n";
  }
  return s;
}

}  // namespace kinegen::codegen

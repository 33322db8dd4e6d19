// AnalysisRows (analysis_rows.hpp): a run's CSV lines, with a suspension's design-position
// offsets and motion ratios.
#include "kinegen/codegen/analysis/analysis_rows.hpp"

#include <string>
#include <vector>

#include "kinegen/codegen/analysis/spatial.hpp"
#include "kinegen/codegen/analysis/suspension.hpp"

namespace kinegen::codegen {

AnalysisRows::AnalysisRows(const CompiledModel& model, const AnalysisOptions& options,
                           long long rows, const std::string& what)
    : model_(model) {
  if (model.mechanism().spatial) spatial_ = std::make_unique<SpatialAnalysis>(model);
  if (!model.mechanism().suspension) return;
  require_kept_rows(what + " with a suspension:", rows, static_cast<std::size_t>(3 * model.nq()));
  suspension_ = std::make_unique<SuspensionRows>(model, options);
}

AnalysisRows::~AnalysisRows() = default;

std::string AnalysisRows::header(std::vector<std::string> forces,
                                 const std::vector<std::string>& sensitivity) const {
  // The motion ratios come after the force columns and before the sensitivities.
  for (const auto& name : SuspensionRows::columns(model_.mechanism())) forces.push_back(name);
  return csv_header(model_.mechanism(), forces, sensitivity);
}

void AnalysisRows::take(const StateRow& row, const LineSink& line) {
  if (!suspension_) return line(text(row, {}));
  kept_.push_back(row);
  suspension_->apply(kept_.back());
}

void AnalysisRows::finish(const LineSink& line) {
  if (!suspension_) return;
  const auto ratios = suspension_->motion_ratios(kept_);
  for (std::size_t k = 0; k < kept_.size(); ++k) line(text(kept_[k], ratios[k]));
  kept_.clear();
}

std::string AnalysisRows::text(const StateRow& row, const std::vector<double>& extra) const {
  // Only spatial files have a suspension, so `extra` is empty on planar ones.
  return spatial_ ? spatial_->csv_row(row, extra)
                  : csv_row(row, static_cast<int>(model_.mechanism().bodies.size()));
}

}  // namespace kinegen::codegen

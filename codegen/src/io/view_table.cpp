// The runs `kinegen view` shows: a CSV read back, an analysis run in-process, a set of modes.
#include <sys/stat.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/interrupt.hpp"
#include "kinegen/codegen/base/read_file.hpp"
#include "kinegen/codegen/io/view.hpp"

namespace kinegen::codegen {

namespace {

// The fields of one CSV line, trimmed of spaces and a final '\r'.
void split_fields(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t begin = 0;
  while (true) {
    const std::size_t end = line.find(',', begin);
    std::string_view f = line.substr(begin, end == std::string_view::npos ? end : end - begin);
    while (!f.empty() && f.front() == ' ') f.remove_prefix(1);
    while (!f.empty() && f.back() == ' ') f.remove_suffix(1);
    out.push_back(f);
    if (end == std::string_view::npos) return;
    begin = end + 1;
  }
}

bool blank(std::string_view line) {
  return line.find_first_not_of(" \r\t") == std::string_view::npos;
}

// A run's CSV, read twice (its rows counted, then read): a regular file from the disk, anything
// else (a pipe, a device, standard input) held in memory, at most kMaxStreamedRunBytes.
class RunSource {
 public:
  explicit RunSource(const std::string& path) : path_(path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
      throw UsageError("cannot read '" + path + "': it is a directory");
    if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) {
      file_.open(path, std::ios::binary);
      if (!file_) throw UsageError("cannot read '" + path + "'");
      in_ = &file_;
      return;
    }
    FileText text = read_bounded(path, kMaxStreamedRunBytes);
    if (!text.ok())
      throw UsageError(text.problem("'" + path + "'", kMaxStreamedRunBytes) +
                       (text.status == FileText::Status::kTooLarge
                            ? " (a run that is not a regular file is held in memory; write it "
                              "to a file first)"
                            : ""));
    memory_.str(std::move(text.text));
    in_ = &memory_;
  }

  // The next line (false at the end), with its 1-based number; a line beyond kMaxCsvLineBytes
  // is refused.
  bool next(std::string& line) {
    bool too_long = false;
    if (!getline_bounded(*in_, line, kMaxCsvLineBytes, &too_long)) return false;
    ++line_number_;
    if (too_long)
      throw InputError(path_, "line " + std::to_string(line_number_), {line_number_},
                       "longer than " + std::to_string(kMaxCsvLineBytes) +
                           " bytes; a run's CSV line is far shorter");
    if (line_number_ % 4096 == 0) interruption_point();
    return true;
  }
  int line_number() const { return line_number_; }

  void rewind() {
    in_->clear();
    in_->seekg(0);
    line_number_ = 0;
  }

 private:
  std::string path_;
  std::ifstream file_;
  std::istringstream memory_;
  std::istream* in_ = nullptr;
  int line_number_ = 0;
};

// The rows below the header: non-blank lines after the first non-blank one.
std::size_t count_rows(RunSource& in) {
  in.rewind();
  std::string line;
  std::size_t lines = 0;
  bool header = false;
  while (in.next(line)) {
    if (blank(line)) continue;
    if (header) ++lines;
    header = true;
  }
  return lines;
}

}  // namespace

std::size_t decimation_stride(std::size_t total, std::size_t max_rows) {
  max_rows = std::max<std::size_t>(max_rows, 2);
  if (total <= max_rows) return 1;
  // Rows 0, s, 2s, ... and the last: ceil((total - 1) / s) + 1 <= max_rows.
  return (total - 1 + (max_rows - 2)) / (max_rows - 1);
}

RunTable read_run_csv(const std::string& path, std::size_t max_rows) {
  RunSource in(path);
  RunTable run;
  run.source = path;
  std::string line;
  std::vector<std::string_view> fields;
  int line_number = 0;
  while (run.columns.empty() && in.next(line)) {
    line_number = in.line_number();
    if (blank(line)) continue;
    split_fields(line, fields);
    std::set<std::string_view> seen;
    for (const auto& f : fields) {
      if (f.empty()) throw InputError(path, "header", {line_number}, "an empty column name");
      if (!seen.insert(f).second)
        throw InputError(path, "header", {line_number},
                         "the column '" + std::string(f) + "' appears twice");
      run.columns.emplace_back(f);
    }
  }
  if (run.columns.empty()) throw InputError(path, "header", {}, "the file is empty");
  const int header_line = line_number;
  run.total_rows = count_rows(in);
  require_kept_rows("view", static_cast<long long>(std::min(run.total_rows, max_rows)),
                    run.columns.size(), "--max-rows");
  // Back to the line after the header.
  in.rewind();
  while (in.line_number() < header_line && in.next(line)) {
  }
  line_number = header_line;
  if (run.total_rows == 0)
    throw InputError(path, "rows", {line_number}, "a header but no rows: nothing to show");
  run.stride = decimation_stride(run.total_rows, max_rows);
  run.values.assign(run.columns.size(), {});
  const std::size_t kept = (run.total_rows - 1 + run.stride - 1) / run.stride + 1;
  for (auto& v : run.values) v.reserve(std::min(kept, run.total_rows));
  std::size_t row = 0;
  while (in.next(line)) {
    line_number = in.line_number();
    if (blank(line)) continue;
    split_fields(line, fields);
    if (fields.size() != run.columns.size())
      throw InputError(path, "row " + std::to_string(row), {line_number},
                       std::to_string(fields.size()) + " values where the header has " +
                           std::to_string(run.columns.size()) + " columns");
    // Every row is read and checked; the kept ones are stored.
    const bool keep = row % run.stride == 0 || row + 1 == run.total_rows;
    for (std::size_t c = 0; c < fields.size(); ++c) {
      double v = 0;
      const auto [end, ec] =
          std::from_chars(fields[c].data(), fields[c].data() + fields[c].size(), v);
      if (ec != std::errc() || end != fields[c].data() + fields[c].size() || fields[c].empty())
        throw InputError(
            path, "row " + std::to_string(row), {line_number},
            "'" + std::string(fields[c]) + "' in column '" + run.columns[c] + "' is not a number");
      if (keep) run.values[c].push_back(v);
    }
    ++row;
  }
  if (row != run.total_rows)  // the file changed between the two passes
    throw UsageError("'" + path + "' changed while it was read");
  return run;
}

RunTable analysis_table(const CompiledModel& model, const TimeGrid& grid, bool forces,
                        std::size_t max_rows, const std::function<void(const std::string&)>& warn,
                        std::string* failure) {
  require_driven(model);
  const Mechanism& m = model.mechanism();
  AnalysisOptions options;
  options.warn = warn;
  ForceModel force_model;
  std::vector<std::string> force_names;
  if (forces) {
    force_model = forces_for_analysis(model, grid.t0);
    force_names = force_columns(m);
    options.forces = &force_model;
  }
  RunTable run;
  run.source = "the analysis (t = " + format_number(grid.t0) + " .. " + format_number(grid.t1) +
               ", " + std::to_string(grid.steps) + " steps)";
  std::string header = csv_header(m, force_names, {});
  header.pop_back();
  std::vector<std::string_view> fields;
  split_fields(header, fields);
  for (const auto& f : fields) run.columns.emplace_back(f);
  run.values.assign(run.columns.size(), {});
  run.total_rows = static_cast<std::size_t>(grid.steps) + 1;
  require_kept_rows("view", static_cast<long long>(std::min(run.total_rows, max_rows)),
                    run.columns.size(), "--max-rows");
  run.stride = decimation_stride(run.total_rows, max_rows);
  // Values as the CSV holds them (csv_row, 17 digits, read back): one column order.
  std::vector<double> last;
  std::size_t row = 0;
  bool last_kept = false;
  const auto sink = [&](const StateRow& state) {
    std::string text = csv_row(state, static_cast<int>(m.bodies.size()));
    text.pop_back();
    split_fields(text, fields);
    last.resize(fields.size());
    for (std::size_t c = 0; c < fields.size(); ++c)
      std::from_chars(fields[c].data(), fields[c].data() + fields[c].size(), last[c]);
    last_kept = row % run.stride == 0 || row + 1 == run.total_rows;
    if (last_kept)
      for (std::size_t c = 0; c < last.size(); ++c) run.values[c].push_back(last[c]);
    ++row;
  };
  try {
    run_analysis(model, grid, sink, options);
  } catch (const AnalysisError& e) {
    if (row == 0 || !failure) throw;
    *failure = e.what();
    if (!last_kept)
      for (std::size_t c = 0; c < last.size(); ++c) run.values[c].push_back(last[c]);
    run.total_rows = row;
  }
  return run;
}

ModeSet read_modes_json(const std::string& path, const CompiledModel& model) {
  const FileText text = read_bounded(path, kMaxModesBytes);
  if (!text.ok()) throw UsageError(text.problem("'" + path + "'", kMaxModesBytes));
  YAML::Node root;
  try {
    root = YAML::Load(text.text);
  } catch (const YAML::Exception& e) {
    throw InputError(path, "modes", {e.mark.line + 1}, e.msg);
  }
  const auto fail = [&](const YAML::Node& at, const std::string& item, const std::string& what) {
    throw InputError(path, item, {at.IsDefined() ? at.Mark().line + 1 : 0}, what);
  };
  if (!root.IsMap()) fail(root, "modes", "expected an object with q, frequencies and shapes");
  const auto labels = coordinate_labels(model.mechanism());
  const int nq = model.nq();
  const auto numbers = [&](const YAML::Node& node, const std::string& item, int size) {
    if (!node.IsSequence()) fail(node, item, "expected a list of numbers");
    if (size >= 0 && static_cast<int>(node.size()) != size)
      fail(node, item,
           std::to_string(node.size()) + " values, expected " + std::to_string(size) +
               " (one per coordinate: " + std::to_string(nq) + ")");
    Eigen::VectorXd v(node.size());
    for (std::size_t k = 0; k < node.size(); ++k) {
      try {
        v[k] = node[k].as<double>();
      } catch (const YAML::Exception&) {
        fail(node[k], item + "[" + std::to_string(k) + "]", "not a number");
      }
      if (!std::isfinite(v[k])) fail(node[k], item + "[" + std::to_string(k) + "]", "not finite");
    }
    return v;
  };
  // `kinegen modes`' JSON adds what the page does not draw (format 7.4: the point, M_z, K_z,
  // C_z, the damped frequencies, ...); those keys are read past, anything else is a mistake.
  const std::string known =
      " coordinates q frequencies shapes t equilibrium stability free z mass stiffness damping "
      "damped_frequencies damping_ratios kinds shapes_z ";
  for (const auto& key : root) {
    const std::string k = key.first.as<std::string>();
    if (known.find(" " + k + " ") == std::string::npos)
      fail(key.first, k,
           "unknown key (the keys are coordinates, q, frequencies, shapes, and those kinegen "
           "modes writes beside them)");
  }
  if (const YAML::Node c = root["coordinates"]) {
    if (!c.IsSequence() || c.size() != labels.size())
      fail(c, "coordinates", "expected the mechanism's " + std::to_string(nq) + " coordinates");
    for (std::size_t k = 0; k < labels.size(); ++k)
      if (c[k].as<std::string>("") != labels[k])
        fail(c[k], "coordinates[" + std::to_string(k) + "]",
             "'" + c[k].as<std::string>("") + "' where the mechanism has '" + labels[k] + "'");
  }
  ModeSet modes;
  modes.source = path;
  for (const char* key : {"q", "frequencies", "shapes"})
    if (!root[key]) fail(root, key, "missing");
  modes.q = numbers(root["q"], "q", nq);
  const Eigen::VectorXd f = numbers(root["frequencies"], "frequencies", -1);
  modes.frequencies.assign(f.data(), f.data() + f.size());
  const YAML::Node shapes = root["shapes"];
  if (!shapes.IsSequence() || shapes.size() != modes.frequencies.size())
    fail(shapes, "shapes",
         "expected one shape per frequency (" + std::to_string(modes.frequencies.size()) + ")");
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    modes.shapes.push_back(numbers(shapes[k], "shapes[" + std::to_string(k) + "]", nq));
    if (modes.shapes.back().cwiseAbs().maxCoeff() == 0)
      fail(shapes[k], "shapes[" + std::to_string(k) + "]", "a shape of zeros");
  }
  if (modes.frequencies.empty()) fail(root["frequencies"], "frequencies", "no modes");
  return modes;
}

}  // namespace kinegen::codegen

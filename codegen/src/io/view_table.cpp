// The runs `kinegen view` shows: a CSV read back, an analysis run in-process, a set of modes.
#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <set>
#include <sstream>

#include "kinegen/codegen/analysis/analysis_rows.hpp"
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
  // The lines analyze writes (analysis_rows.hpp), read back: one column order, and a
  // suspension's travel and motion ratios as analyze gives them.
  AnalysisRows lines(model, options, grid.steps + 1LL, "view");
  RunTable run;
  run.source = "the analysis (t = " + format_number(grid.t0) + " .. " + format_number(grid.t1) +
               ", " + std::to_string(grid.steps) + " steps)";
  std::string header = lines.header(force_names, {});
  header.pop_back();
  std::vector<std::string_view> fields;
  split_fields(header, fields);
  for (const auto& f : fields) run.columns.emplace_back(f);
  run.values.assign(run.columns.size(), {});
  run.total_rows = static_cast<std::size_t>(grid.steps) + 1;
  require_kept_rows("view", static_cast<long long>(std::min(run.total_rows, max_rows)),
                    run.columns.size(), "--max-rows");
  run.stride = decimation_stride(run.total_rows, max_rows);
  std::vector<double> last;
  std::size_t row = 0, solved = 0;
  bool last_kept = false;
  const auto keep = [&](const std::string& line) {
    std::string_view text(line);
    text.remove_suffix(1);  // the line break
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
    run_analysis(
        model, grid,
        [&](const StateRow& state) {
          ++solved;
          lines.take(state, keep);
        },
        options);
  } catch (const AnalysisError& e) {
    if (solved == 0 || !failure) throw;
    *failure = e.what();
    run.total_rows = solved;
    lines.finish(keep);
    if (!last_kept)
      for (std::size_t c = 0; c < last.size(); ++c) run.values[c].push_back(last[c]);
    return run;
  }
  lines.finish(keep);
  return run;
}

namespace {

// A modes JSON is parsed here rather than by yaml-cpp, whose nodes cost some 200 bytes of memory
// per byte of text and which reads a flow map's key of any kind: the text is bounded before it
// is read (modes_bytes_limit), the nesting while it is parsed, and each value costs one node.
struct JsonValue {
  enum class Kind { kNull, kBool, kNumber, kString, kArray, kObject };
  Kind kind = Kind::kNull;
  double number = 0;
  std::string text;               // a string's value
  std::vector<JsonValue> items;   // an array's values, an object's values
  std::vector<std::string> keys;  // an object's keys (items[k] is keys[k]'s value)
  int line = 0;
  const JsonValue* find(const std::string& key) const {
    for (std::size_t k = 0; k < keys.size(); ++k)
      if (keys[k] == key) return &items[k];
    return nullptr;
  }
};

// Deeper than this is not a modes JSON (the shapes and the matrices are 3 levels).
constexpr int kMaxModesDepth = 8;

class JsonParser {
 public:
  // budget: the most values kept (those of the keys the page reads; the others are parsed and
  // dropped), from the mechanism's size.
  JsonParser(const std::string& path, const std::string& text, std::size_t budget)
      : path_(path), text_(text), budget_(budget) {}

  JsonValue parse() {
    JsonValue v = value(1, true);
    space();
    if (at_ < text_.size()) fail("modes", "text after the JSON value: " + excerpt());
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& item, const std::string& what) const {
    throw InputError(path_, item, {line_}, what);
  }
  // The text at the parser, for a message: up to 24 characters, on one line.
  std::string excerpt() const {
    if (at_ >= text_.size()) return "the end of the file";
    std::string out = "'";
    for (std::size_t k = at_; k < text_.size() && k < at_ + 24; ++k) {
      const char ch = text_[k];
      if (ch == '\n' || ch == '\r') break;
      out += static_cast<unsigned char>(ch) < 0x20 ? ' ' : ch;
    }
    return out + "'";
  }
  // A key that is not a string, as written: up to its ':' on its line (at most 40 characters).
  std::string key_excerpt() const {
    std::string out;
    for (std::size_t k = at_; k < text_.size() && out.size() < 40; ++k) {
      const char ch = text_[k];
      if (ch == ':' || ch == '\n' || ch == '\r') break;
      out += static_cast<unsigned char>(ch) < 0x20 ? ' ' : ch;
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    return out.empty() ? excerpt() : out;
  }
  void space() {
    while (at_ < text_.size()) {
      const char ch = text_[at_];
      if (ch == '\n') ++line_;
      if (ch != ' ' && ch != '\t' && ch != '\n' && ch != '\r') return;
      ++at_;
    }
  }
  bool take(const char* word) {
    const std::size_t n = std::strlen(word);
    if (text_.compare(at_, n, word) != 0) return false;
    at_ += n;
    return true;
  }

  // The value at the parser; built when `keep`, else only read past. At the root, the values of
  // the keys the page does not read are read past (their keys are kept, to be checked).
  JsonValue value(int depth, bool keep) {
    space();
    if (depth > kMaxModesDepth)
      fail("modes", "nested deeper than " + std::to_string(kMaxModesDepth) +
                        " levels; a modes JSON has 3 (its shapes, lists of lists of numbers)");
    if (++values_ % 65536 == 0) interruption_point();
    if (keep && ++kept_ > budget_)
      fail("modes", "more than " + std::to_string(budget_) +
                        " values in its coordinates, q, frequencies and shapes, more than the "
                        "mechanism's coordinates have");
    JsonValue v;
    v.line = line_;
    if (at_ >= text_.size()) fail("modes", "the file ends where a value should be");
    const char ch = text_[at_];
    if (ch == '{' || ch == '[') {
      const char close = ch == '{' ? '}' : ']';
      v.kind = ch == '{' ? JsonValue::Kind::kObject : JsonValue::Kind::kArray;
      ++at_;
      space();
      if (at_ < text_.size() && text_[at_] == close) {
        ++at_;
        return v;
      }
      std::string key;
      while (true) {
        space();
        if (v.kind == JsonValue::Kind::kObject) {
          if (at_ >= text_.size() || text_[at_] != '"')
            fail("key " + key_excerpt(),
                 "a key must be a string in double quotes (the keys are q, frequencies, shapes, "
                 "...)");
          key = string();
          if (keep) v.keys.push_back(key);
          space();
          if (at_ >= text_.size() || text_[at_] != ':')
            fail(key, "expected ':' after the key, found " + excerpt());
          ++at_;
        }
        const bool read = depth > 1 || v.kind != JsonValue::Kind::kObject || key == "q" ||
                          key == "frequencies" || key == "shapes" || key == "coordinates";
        JsonValue item = value(depth + 1, keep && read);
        if (keep) v.items.push_back(std::move(item));
        space();
        if (at_ < text_.size() && text_[at_] == ',') {
          ++at_;
          continue;
        }
        if (at_ < text_.size() && text_[at_] == close) {
          ++at_;
          return v;
        }
        fail("modes", std::string("expected ',' or '") + close + "', found " + excerpt());
      }
    }
    if (ch == '"') {
      v.kind = JsonValue::Kind::kString;
      v.text = string();
      return v;
    }
    if (take("null")) return v;
    if (take("true") || take("false")) {
      v.kind = JsonValue::Kind::kBool;
      return v;
    }
    // Numbers, and the NaN and Infinity that Python's json module writes for non-finite ones.
    v.kind = JsonValue::Kind::kNumber;
    if (take("NaN")) {
      v.number = std::numeric_limits<double>::quiet_NaN();
      return v;
    }
    const bool minus = text_[at_] == '-';
    if (take(minus ? "-Infinity" : "Infinity")) {
      v.number = minus ? -HUGE_VAL : HUGE_VAL;
      return v;
    }
    std::size_t end = at_;
    while (end < text_.size() && text_[end] != 0 && std::strchr("+-0123456789.eE", text_[end]))
      ++end;
    const auto [stop, ec] = std::from_chars(text_.data() + at_, text_.data() + end, v.number);
    if (end == at_ || ec == std::errc::invalid_argument || stop != text_.data() + end)
      fail("modes",
           "expected a value (a number, a string, a list or an object), found " + excerpt());
    if (ec == std::errc::result_out_of_range)  // beyond a double: inf or 0, as strtod reads it
      v.number = std::strtod(text_.substr(at_, end - at_).c_str(), nullptr);
    at_ = end;
    return v;
  }

  std::string string() {
    const int line = line_;
    ++at_;  // the opening quote
    std::string out;
    while (at_ < text_.size() && text_[at_] != '"') {
      char ch = text_[at_++];
      if (ch == '\n') fail("modes", "a string is not closed on its line");
      if (ch == '\\' && at_ < text_.size()) {
        ch = text_[at_++];
        if (ch == 'u') {  // kept as written: no key or value read here needs it decoded
          out += "\\u";
          continue;
        }
        const char* from = "\"\\/bfnrt";
        const char* to = "\"\\/\b\f\n\r\t";
        const char* k = std::strchr(from, ch);
        if (!k || ch == 0) fail("modes", std::string("an unknown escape \\") + ch + " in a string");
        ch = to[k - from];
      }
      out += ch;
    }
    if (at_ >= text_.size()) {
      line_ = line;
      fail("modes", "a string is not closed");
    }
    ++at_;
    return out;
  }

  const std::string& path_;
  const std::string& text_;
  std::size_t budget_, at_ = 0, values_ = 0, kept_ = 0;
  int line_ = 1;
};

// The largest modes JSON of a mechanism with nq coordinates: `kinegen modes` writes fewer than
// 8 (nq + 1)^2 numbers (q, the shapes as dq and dz, M_z, K_z, C_z, the frequencies), each in
// under 26 characters; this allows 64 a number (a file written with indentation, one number a
// line) and 64 KiB besides, within kMaxModesBytes.
std::size_t modes_bytes_limit(int nq) {
  const auto n = static_cast<std::size_t>(nq) + 1;
  return std::min(kMaxModesBytes, (std::size_t{64} << 10) + 8 * n * n * 64);
}

}  // namespace

ModeSet read_modes_json(const std::string& path, const CompiledModel& model) {
  const int nq = model.nq();
  const std::size_t limit = modes_bytes_limit(nq);
  const FileText text = read_bounded(path, limit);
  if (!text.ok())
    throw UsageError(text.problem("'" + path + "'", limit) +
                     (text.status == FileText::Status::kTooLarge
                          ? ", the most a modes JSON of " + model.mechanism().source + " (" +
                                std::to_string(nq) + " coordinates) may be"
                          : ""));
  // Kept: the object, coordinates, q, frequencies (at most nq) and shapes (as many, of nq each)
  // with their lists: at most (nq + 2)^2 + 1 values.
  const auto n = static_cast<std::size_t>(nq) + 2;
  const std::size_t budget = n * n + 8;
  const JsonValue root = JsonParser(path, text.text, budget).parse();
  const auto fail = [&](const JsonValue* at, const std::string& item, const std::string& what) {
    throw InputError(path, item, {at ? at->line : 0}, what);
  };
  if (root.kind != JsonValue::Kind::kObject)
    fail(&root, "modes", "expected an object with q, frequencies and shapes");
  const auto labels = coordinate_labels(model.mechanism());
  const auto numbers = [&](const JsonValue& node, const std::string& item, int size) {
    if (node.kind != JsonValue::Kind::kArray) fail(&node, item, "expected a list of numbers");
    if (size >= 0 && static_cast<int>(node.items.size()) != size)
      fail(&node, item,
           std::to_string(node.items.size()) + " values, expected " + std::to_string(size) +
               " (one per coordinate: " + std::to_string(nq) + ")");
    Eigen::VectorXd v(node.items.size());
    for (std::size_t k = 0; k < node.items.size(); ++k) {
      const JsonValue& x = node.items[k];
      if (x.kind != JsonValue::Kind::kNumber)
        fail(&x, item + "[" + std::to_string(k) + "]", "not a number");
      v[k] = x.number;
      if (!std::isfinite(v[k])) fail(&x, item + "[" + std::to_string(k) + "]", "not finite");
    }
    return v;
  };
  // `kinegen modes`' JSON adds what the page does not draw (docs/linear.md: the point, M_z, K_z,
  // C_z, the damped frequencies, ...); those keys are read past, anything else is a mistake.
  const std::string known =
      " coordinates q frequencies shapes t equilibrium stability free z mass stiffness damping "
      "damped_frequencies damping_ratios kinds shapes_z ";
  for (std::size_t k = 0; k < root.keys.size(); ++k) {
    const std::string& key = root.keys[k];
    if (key.find(' ') != std::string::npos || known.find(" " + key + " ") == std::string::npos)
      fail(&root.items[k], key,
           "unknown key (the keys are coordinates, q, frequencies, shapes, and those kinegen "
           "modes writes beside them)");
    for (std::size_t j = 0; j < k; ++j)
      if (root.keys[j] == key) fail(&root.items[k], key, "given twice");
  }
  if (const JsonValue* c = root.find("coordinates")) {
    if (c->kind != JsonValue::Kind::kArray || c->items.size() != labels.size())
      fail(c, "coordinates", "expected the mechanism's " + std::to_string(nq) + " coordinates");
    for (std::size_t k = 0; k < labels.size(); ++k) {
      const JsonValue& x = c->items[k];
      const std::string name = x.kind == JsonValue::Kind::kString ? x.text : "";
      if (name != labels[k])
        fail(&x, "coordinates[" + std::to_string(k) + "]",
             "'" + name + "' where the mechanism has '" + labels[k] + "'");
    }
  }
  ModeSet modes;
  modes.source = path;
  for (const char* key : {"q", "frequencies", "shapes"})
    if (!root.find(key)) fail(&root, key, "missing");
  modes.q = numbers(*root.find("q"), "q", nq);
  const JsonValue& frequencies = *root.find("frequencies");
  // A mechanism has at most one mode per coordinate: more would only cost the page memory.
  if (frequencies.kind == JsonValue::Kind::kArray && frequencies.items.size() > labels.size())
    fail(&frequencies, "frequencies",
         std::to_string(frequencies.items.size()) + " modes; the mechanism has at most " +
             std::to_string(nq) + " (one per coordinate)");
  const Eigen::VectorXd f = numbers(frequencies, "frequencies", -1);
  modes.frequencies.assign(f.data(), f.data() + f.size());
  const JsonValue& shapes = *root.find("shapes");
  if (shapes.kind != JsonValue::Kind::kArray || shapes.items.size() != modes.frequencies.size())
    fail(&shapes, "shapes",
         "expected one shape per frequency (" + std::to_string(modes.frequencies.size()) + ")");
  for (std::size_t k = 0; k < shapes.items.size(); ++k) {
    modes.shapes.push_back(numbers(shapes.items[k], "shapes[" + std::to_string(k) + "]", nq));
    if (modes.shapes.back().cwiseAbs().maxCoeff() == 0)
      fail(&shapes.items[k], "shapes[" + std::to_string(k) + "]", "a shape of zeros");
  }
  if (modes.frequencies.empty()) fail(&frequencies, "frequencies", "no modes");
  return modes;
}

}  // namespace kinegen::codegen

// `kinegen view`'s page: the run checked against the mechanism, the drawing (animate_drawing),
// the data and the page's template (viewer/, with uPlot, embedded at build time) put together.
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/base/diagnostics.hpp"
#include "kinegen/codegen/base/version.hpp"
#include "kinegen/codegen/io/view.hpp"
#include "view_json.hpp"

#ifdef KINEGEN_HAVE_VIEWER
#include <zlib.h>

#include "kinegen/codegen/io/viewer_assets.hpp"
#endif

namespace kinegen::codegen {

using view::Columns;
using view::Json;

namespace {

static_assert(std::endian::native == std::endian::little,
              "the page reads the run as little-endian doubles (Float64Array)");

std::string base64(const unsigned char* data, std::size_t size) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  std::size_t k = 0;
  for (; k + 2 < size; k += 3) {
    const unsigned v = data[k] << 16 | data[k + 1] << 8 | data[k + 2];
    for (int s : {18, 12, 6, 0}) out += kAlphabet[(v >> s) & 63];
  }
  if (k < size) {
    const unsigned v = data[k] << 16 | (k + 1 < size ? data[k + 1] << 8 : 0);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += k + 1 < size ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

Eigen::Vector2d world(const Eigen::VectorXd& q, int body, const Eigen::Vector2d& s) {
  if (body == kGround) return s;
  const double phi = q[3 * body + 2];
  const auto r = point_position(&q[3 * body], std::cos(phi), std::sin(phi), s[0], s[1]);
  return {r[0], r[1]};
}

// What the page says of a row that may be one of several kept: its time too.
std::string row_name(const RunTable& run, std::size_t k, int time) {
  const std::size_t row = k + 1 == run.rows() ? run.total_rows - 1 : k * run.stride;
  return "row " + std::to_string(row) +
         (time >= 0 ? " (t = " + format_number(run.values[time][k]) + ")" : "");
}

// The positions of each kept row, from the columns coordinate_labels names.
std::vector<Eigen::VectorXd> positions(const CompiledModel& model, const RunTable& run,
                                       const Columns& columns, std::vector<int>& q_columns) {
  const auto labels = coordinate_labels(model.mechanism());
  std::string missing;
  int count = 0;
  for (const auto& label : labels) {
    q_columns.push_back(columns.find(label));
    if (q_columns.back() < 0 && count++ < 6) missing += (missing.empty() ? "" : ", ") + label;
  }
  if (count > 0) {
    std::string has;
    for (std::size_t c = 0; c < run.columns.size() && c < 8; ++c)
      has += (c ? ", " : "") + run.columns[c];
    if (run.columns.size() > 8) has += ", ... (" + std::to_string(run.columns.size()) + ")";
    throw InputError(run.source, "columns", {1},
                     "not a run of " + model.mechanism().source + ": no column " + missing +
                         (count > 6 ? " and " + std::to_string(count - 6) + " more" : "") +
                         " (its columns: " + has + ")");
  }
  const int time = columns.find("t");
  std::vector<Eigen::VectorXd> q(run.rows(), Eigen::VectorXd(labels.size()));
  for (std::size_t k = 0; k < run.rows(); ++k)
    for (std::size_t i = 0; i < labels.size(); ++i) {
      q[k][i] = run.values[q_columns[i]][k];
      if (!std::isfinite(q[k][i]))
        throw InputError(run.source, row_name(run, k, time), {},
                         labels[i] + " is not a number: no position to draw");
    }
  return q;
}

// The joints hold at every row and the named points are where the positions put them, or the
// run is of another mechanism or other parameters, and its drawing would mislead.
void check_matches(const CompiledModel& model, const RunTable& run, const Columns& columns,
                   const std::vector<Eigen::VectorXd>& q) {
  const Mechanism& m = model.mechanism();
  const double tol = 1e-6 * std::max(1.0, model.symbolic().length_scale);
  const int time = columns.find("t");
  ModelEvaluator<double> evaluator(model);
  Eigen::VectorXd phi(model.nc());
  const auto offsets3 =
      m.spatial ? view::space_point_offsets(model) : std::vector<Eigen::Vector3d>{};
  for (std::size_t k = 0; k < q.size(); ++k) {
    evaluator.phi(q[k].data(), time >= 0 ? run.values[time][k] : 0.0, phi.data());
    for (int r = 0; r < model.nc(); ++r) {
      if (model.symbolic().rows[r].constraint->is_driver || std::abs(phi[r]) <= tol) continue;
      throw InputError(run.source, row_name(run, k, time), {},
                       "the positions break " + model.row_label(r) + " of " + m.source + " by " +
                           format_number(std::abs(phi[r]), NumberStyle::kShort) +
                           ": a run of another mechanism, or made with other --param values?");
    }
    for (std::size_t p = 0; p < m.points.size(); ++p) {
      const int x = columns.find(m.points[p].name + ".x"),
                y = columns.find(m.points[p].name + ".y"),
                z = m.spatial ? columns.find(m.points[p].name + ".z") : -2;
      if (x < 0 || y < 0 || z == -1) continue;
      double away = 0;
      if (m.spatial) {
        const Eigen::Vector3d given(run.values[x][k], run.values[y][k], run.values[z][k]);
        away = (view::space_world(q[k], m.points[p].body, offsets3[p]) - given).norm();
      } else {
        const Eigen::Vector2d given(run.values[x][k], run.values[y][k]);
        away = (world(q[k], m.points[p].body, model.point_offsets()[p]) - given).norm();
      }
      if (away <= tol) continue;
      throw InputError(
          run.source, row_name(run, k, time), {},
          "point " + m.points[p].name + " is " + format_number(away, NumberStyle::kShort) +
              " away from where the positions put it in " + m.source + ": other --param values?");
    }
  }
}

// The columns as doubles: constant ones by value, the others one after another in one block.
// The stored columns packed for the page: each value's 64 bits as an integer less the one
// before it in its column (smooth runs make small differences), the 8 bytes of every value in
// 8 planes (high bytes compress to almost nothing), deflated (zlib), so a run of 1e5 rows
// weighs about 40% of its doubles; the page undoes each step exactly (drawing.js).
std::string pack(const std::vector<double>& stored, std::size_t rows) {
  const std::size_t n = stored.size();
  std::vector<unsigned char> planes(8 * n);
  std::uint64_t previous = 0;
  for (std::size_t k = 0; k < n; ++k) {
    std::uint64_t bits;
    std::memcpy(&bits, &stored[k], sizeof bits);
    const std::uint64_t delta = k % rows == 0 ? bits : bits - previous;  // modulo 2^64
    previous = bits;
    for (int b = 0; b < 8; ++b) planes[b * n + k] = static_cast<unsigned char>(delta >> (8 * b));
  }
#ifdef KINEGEN_HAVE_VIEWER
  uLongf size = compressBound(static_cast<uLong>(planes.size()));
  std::vector<unsigned char> deflated(size);
  if (compress2(deflated.data(), &size, planes.data(), static_cast<uLong>(planes.size()), 1) !=
      Z_OK)
    throw std::runtime_error("zlib could not compress the page's data");
  return base64(deflated.data(), size);
#else
  return {};  // not reached: view_html requires the viewer
#endif
}

void write_values(Json& json, const RunTable& run, std::string& blob) {
  std::vector<double> stored;
  stored.reserve(run.columns.size() * run.rows());
  json.key("layout").open('[');
  int next = 0;
  for (const auto& column : run.values) {
    bool constant = true;
    for (const double v : column)
      if (std::memcmp(&v, &column[0], sizeof v) != 0) {
        constant = false;
        break;
      }
    json.item();
    if (constant && std::isfinite(column[0])) {
      json.open('{').key("value").number(column[0]).close('}');
    } else {
      json.raw(std::to_string(next++));
      stored.insert(stored.end(), column.begin(), column.end());
    }
  }
  json.close(']').key("packing").string("delta-planes-deflate");
  blob = stored.empty() ? "" : pack(stored, run.rows());
}

void header(Json& json, const CompiledModel& model, const ViewOptions& options) {
  json.key("kinegen").string(kVersion).key("mechanism").string(model.mechanism().name);
  json.key("file").string(model.mechanism().source).key("failure").string(options.failure);
  json.key("notes").open('[');
  for (const auto& n : options.notes) json.item().string(n);
  json.close(']');
}

// A spatial page adds three.js (space.html: its ES modules as text, which the page imports
// from blob: URLs of its own making, the only scripts its policy then admits besides inline).
std::string page(const std::string& data, const std::string& blob, bool spatial = false) {
  require_viewer();
  std::string out;
#ifdef KINEGEN_HAVE_VIEWER
  out.reserve(data.size() + blob.size() + (spatial ? (1 << 20) : 0) + (1 << 18));
  for (const char* const* part = embedded::kViewerHead; *part; ++part) out += *part;
  if (spatial) {
    const std::string policy = "script-src 'unsafe-inline'";
    const std::size_t at = out.find(policy);
    if (at == std::string::npos) throw std::logic_error("the page's head lacks its script policy");
    out.insert(at + policy.size(), " blob:");
  }
  out += "<script type=\"application/json\" id=\"kinegen-data\">" + data + "</script>\n";
  out += "<script type=\"text/plain\" id=\"kinegen-values\">";
  out += blob;
  out += "</script>\n";
  if (spatial)
    for (const char* const* part = embedded::kViewerSpace; *part; ++part) out += *part;
  for (const char* const* part = embedded::kViewerTail; *part; ++part) out += *part;
#else
  (void)data;
  (void)blob;
  (void)spatial;
#endif
  return out;
}

}  // namespace

bool viewer_built() {
#ifdef KINEGEN_HAVE_VIEWER
  return true;
#else
  return false;
#endif
}

void require_viewer() {
  if (!viewer_built())
    throw UsageError(
        "this kinegen was built without the viewer (configure with -DKINEGEN_BUILD_VIEWER=ON "
        "after `npm ci` in viewer/)");
}

std::string view_html(const CompiledModel& model, const RunTable& run, const ViewOptions& options) {
  require_viewer();  // before any work
  if (run.rows() == 0) throw InputError(run.source, "rows", {}, "no rows: nothing to show");
  const Columns columns(run.columns);
  if (columns.find("t") < 0)
    throw InputError(run.source, "columns", {1}, "no column t (the time of each row)");
  std::vector<int> q_columns;
  std::vector<Eigen::VectorXd> q = positions(model, run, columns, q_columns);
  check_matches(model, run, columns, q);
  const bool spatial = model.mechanism().spatial;
  const AnimateDrawing drawing =
      spatial ? AnimateDrawing{} : animate_drawing(model, std::move(q), options.width);
  Json json;
  json.open('{');
  header(json, model, options);
  json.key("run").string(run.source).key("rows").raw(std::to_string(run.rows()));
  json.key("total_rows").raw(std::to_string(run.total_rows));
  json.key("stride").raw(std::to_string(run.stride));
  json.key("time").raw(std::to_string(columns.find("t"))).key("columns").open('[');
  for (const auto& c : run.columns) json.item().string(c);
  json.close(']').key("coordinates").open('[');
  for (int c : q_columns) json.item().raw(std::to_string(c));
  json.close(']');
  std::string blob;
  write_values(json, run, blob);
  json.key("space").string(spatial ? "3d" : "2d").key("scene").open('{');
  if (spatial)
    view::write_space_scene(json, model, columns);
  else
    view::write_scene(json, model, drawing, columns);
  json.close('}').close('}');
  return page(json.text(), blob, spatial);
}

std::string view_modes_html(const CompiledModel& model, const ModeSet& modes,
                            const ViewOptions& options) {
  require_viewer();
  const auto labels = coordinate_labels(model.mechanism());
  const auto& scales = model.symbolic().coordinate_scales;
  // Each mode's default amplitude: its largest coordinate moves a tenth of its scale.
  std::vector<double> amplitude;
  std::vector<Eigen::VectorXd> q;
  for (const auto& shape : modes.shapes) {
    double largest = 0;
    for (int i = 0; i < shape.size(); ++i)
      largest = std::max(largest, std::abs(shape[i]) / scales[i]);
    amplitude.push_back(0.1 / largest);
    for (int k = 0; k < 16; ++k)  // the extents and attachments over the oscillation
      q.push_back(modes.q + amplitude.back() * std::sin(2 * M_PI * k / 16) * shape);
  }
  RunTable equilibrium;
  equilibrium.source = modes.source;
  equilibrium.columns = labels;
  for (int i = 0; i < modes.q.size(); ++i) equilibrium.values.push_back({modes.q[i]});
  equilibrium.total_rows = 1;
  const Columns columns(labels);
  check_matches(model, equilibrium, columns, {modes.q});
  const AnimateDrawing drawing = animate_drawing(model, std::move(q), options.width);
  Json json;
  json.open('{');
  header(json, model, options);
  json.key("run").string(modes.source).key("columns").open('[');
  for (const auto& c : labels) json.item().string(c);
  json.close(']').key("modes").open('{').key("q").open('[');
  for (int i = 0; i < modes.q.size(); ++i) json.item().number(modes.q[i]);
  json.close(']').key("frequencies").open('[');
  for (double f : modes.frequencies) json.item().number(f);
  json.close(']').key("amplitudes").open('[');
  for (double a : amplitude) json.item().number(a);
  json.close(']').key("shapes").open('[');
  for (const auto& shape : modes.shapes) {
    json.item().open('[');
    for (int i = 0; i < shape.size(); ++i) json.item().number(shape[i]);
    json.close(']');
  }
  json.close(']').close('}').key("scene").open('{');
  view::write_scene(json, model, drawing, columns);
  json.close('}').close('}');
  return page(json.text(), "");
}

}  // namespace kinegen::codegen

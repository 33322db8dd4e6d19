// Tables: a careful CSV reader and the two spline fits (see table.hpp).
#include "kinegen/codegen/model/table.hpp"

#include <cln/cln.h>

#include <Eigen/SparseLU>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/read_file.hpp"
#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/kernels/spline.hpp"

namespace kinegen::codegen {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const TableSource& src, const std::string& message) {
  throw InputError(src.mechanism_file, src.item, src.loc, message);
}

// A whole field as a finite double, or false.
bool parse_number(std::string field, double& out) {
  const auto first = field.find_first_not_of(" \t");
  const auto last = field.find_last_not_of(" \t\r");
  if (first == std::string::npos) return false;
  field = field.substr(first, last - first + 1);
  char* end = nullptr;
  errno = 0;
  out = std::strtod(field.c_str(), &end);
  return end == field.c_str() + field.size() && errno == 0;
}

// The file the path names, checked to stay inside the mechanism's folder when confined.
fs::path resolve(const std::string& path, const TableSource& src) {
  const fs::path base = fs::path(src.mechanism_file).parent_path();
  const fs::path full = fs::path(path).is_absolute() ? fs::path(path) : base / path;
  std::error_code ec;
  if (!fs::exists(full, ec)) fail(src, "the table file '" + path + "' does not exist");
  if (src.confine) {
    const fs::path root = fs::weakly_canonical(base.empty() ? fs::path(".") : base, ec);
    const fs::path target = fs::canonical(full, ec);
    if (ec) fail(src, "cannot resolve the table file '" + path + "'");
    const auto rel = target.lexically_relative(root);
    if (rel.empty() || *rel.begin() == "..")
      fail(src, "the table file '" + path +
                    "' lies outside the mechanism's folder (by '..', an absolute path or a "
                    "link); copy it next to the mechanism file");
  }
  if (!fs::is_regular_file(full, ec)) fail(src, "the table '" + path + "' is not a regular file");
  return full;
}

// Solves A m = rhs for the spline's second derivatives (A sparse, banded or cyclic).
std::vector<double> solve(const std::vector<Eigen::Triplet<double>>& entries,
                          const Eigen::VectorXd& rhs) {
  Eigen::SparseMatrix<double> a(rhs.size(), rhs.size());
  a.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  lu.compute(a);
  const Eigen::VectorXd m = lu.solve(rhs);
  return std::vector<double>(m.data(), m.data() + m.size());
}

// The live tables. A number's spline is reached through two levels of atomic pointers, so
// that evaluation takes no lock while registration and release (under the mutex) change
// slots: a chunk, once made, is never moved or freed, a slot's spline is published (release)
// before its number is handed out, and it is cleared only when no mechanism holds the number.
// A number is the slot's index plus kMaxTables times its generation, which each release
// advances: a number kept past its table's release (an expression or an evaluator that
// outlived its mechanism) no longer matches its slot, also once the slot holds another table.
constexpr int kChunkSize = 1024;
constexpr int kChunks = kMaxTables / kChunkSize;
// Every number fits an int; a slot whose generations are used up is not reused.
constexpr int kGenerations = static_cast<int>(std::numeric_limits<int>::max() / kMaxTables);

struct Slot {
  std::atomic<const Spline*> spline{nullptr};
  std::atomic<int> generation{0};
};

struct Registry {
  std::mutex mutex;  // registration and release
  std::atomic<Slot*> chunks[kChunks] = {};
  std::vector<int> free_ids;  // released numbers, reused first
  int next = 0;               // numbers below it have been used
  int live = 0;
  // The live tables by a hash of their values, for sharing equal ones.
  std::unordered_multimap<std::size_t, std::pair<int, std::weak_ptr<const TableSlot>>> by_hash;
};

Registry& registry() {
  static Registry* r = new Registry;  // never destroyed: slots may be released at exit
  return *r;
}

std::size_t hash_of(const Spline& s) {
  std::size_t h = std::hash<double>()(s.period) ^ (std::hash<double>()(s.rise) << 1) ^
                  (s.periodic ? 0x9e3779b97f4a7c15ull : 0);
  for (const std::vector<double>* v : {&s.t, &s.y, &s.m})
    for (double x : *v) h = h * 1099511628211ull ^ std::hash<double>()(x);
  return h;
}

bool same(const Spline& a, const Spline& b) {
  return a.t == b.t && a.y == b.y && a.m == b.m && a.periodic == b.periodic &&
         a.period == b.period && a.rise == b.rise;
}

// The slot of a number (of any generation), or null.
Slot* slot_of(Registry& r, int id) {
  if (id < 0) return nullptr;
  const int index = id % kMaxTables;
  Slot* chunk = r.chunks[index / kChunkSize].load(std::memory_order_acquire);
  return chunk ? &chunk[index % kChunkSize] : nullptr;
}

}  // namespace

TableSlot::~TableSlot() {
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  Slot& slot = *slot_of(r, id_);
  const int generation = slot.generation.load(std::memory_order_relaxed) + 1;
  slot.generation.store(generation, std::memory_order_release);
  const Spline* spline = slot.spline.exchange(nullptr, std::memory_order_acq_rel);
  const auto [first, last] = r.by_hash.equal_range(hash_of(*spline));
  for (auto it = first; it != last; ++it)
    if (it->second.first == id_) {
      r.by_hash.erase(it);
      break;
    }
  delete spline;
  if (generation < kGenerations) r.free_ids.push_back(id_ % kMaxTables);
  --r.live;
}

TableRef register_table(const Spline& spline, const TableSource& source) {
  Registry& r = registry();
  const std::size_t h = hash_of(spline);
  std::lock_guard<std::mutex> lock(r.mutex);
  const auto [first, last] = r.by_hash.equal_range(h);
  for (auto it = first; it != last; ++it)
    if (TableRef held = it->second.second.lock();
        held && same(*slot_of(r, held->id())->spline.load(std::memory_order_relaxed), spline))
      return held;
  int index = 0;
  if (!r.free_ids.empty()) {
    index = r.free_ids.back();
    r.free_ids.pop_back();
  } else {
    if (r.next >= kMaxTables)
      fail(source, "more than " + std::to_string(kMaxTables) +
                       " different tables are in use at once in this process; release "
                       "mechanisms that are no longer needed");
    index = r.next++;
    auto& chunk = r.chunks[index / kChunkSize];
    if (!chunk.load(std::memory_order_relaxed))
      chunk.store(new Slot[kChunkSize](), std::memory_order_release);
  }
  Slot& slot = *slot_of(r, index);
  const int id = index + kMaxTables * slot.generation.load(std::memory_order_relaxed);
  slot.spline.store(new Spline(spline), std::memory_order_release);
  TableRef ref = std::make_shared<const TableSlot>(id);
  r.by_hash.emplace(h, std::make_pair(id, std::weak_ptr<const TableSlot>(ref)));
  ++r.live;
  return ref;
}

const Spline& registered_table(int id) {
  Slot* slot = slot_of(registry(), id);
  const Spline* spline = slot ? slot->spline.load(std::memory_order_acquire) : nullptr;
  if (!spline || slot->generation.load(std::memory_order_acquire) != id / kMaxTables)
    throw std::logic_error("table " + std::to_string(id) +
                           " is no longer registered: the mechanism that owned it is gone, and "
                           "an expression or evaluator that read it outlived it");
  return *spline;
}

int live_tables() {
  Registry& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  return r.live;
}

GiNaC::numeric spline_high_precision(const Spline& s, int order, const GiNaC::numeric& x) {
  using GiNaC::numeric;
  const auto exact = [](double v) {
    return numeric(cln::rational(cln::the<cln::cl_R>(numeric(v).to_cl_N())));
  };
  numeric local = x.real();
  numeric turns = 0;
  if (s.periodic) {
    const numeric p = exact(s.period);
    turns = numeric(cln::floor1(cln::the<cln::cl_R>((local / p).to_cl_N())));
    local = local - turns * p;
  }
  const double xd = local.to_double();
  const int n = static_cast<int>(s.t.size());
  const double slack = 8 * std::numeric_limits<double>::epsilon() *
                       std::max(std::abs(s.t.front()), std::abs(s.t.back()));
  if (!(xd >= s.t.front() - slack && xd <= s.t.back() + slack) || order < 0 || order > 2)
    throw AnalysisError("t = " + std::to_string(x.real().to_double()) +
                        " lies outside a table's range in the high-precision evaluation");
  int lo = 0, hi = n - 1;
  while (hi - lo > 1) {
    const int mid = lo + (hi - lo) / 2;
    (s.t[mid] <= xd ? lo : hi) = mid;
  }
  const numeric h = exact(s.t[lo + 1]) - exact(s.t[lo]);
  const numeric a = (exact(s.t[lo + 1]) - local) / h, b = 1 - a;
  const numeric yl = exact(s.y[lo]), yr = exact(s.y[lo + 1]);
  const numeric ml = exact(s.m[lo]), mr = exact(s.m[lo + 1]);
  numeric v;
  if (order == 0)
    v = a * yl + b * yr + ((a * a * a - a) * ml + (b * b * b - b) * mr) * h * h / 6;
  else if (order == 1)
    v = (yr - yl) / h + ((1 - 3 * a * a) * ml + (3 * b * b - 1) * mr) * h / 6;
  else
    v = a * ml + b * mr;
  if (s.periodic && order == 0) v = v + exact(s.rise) * x.real() / exact(s.period);
  if (s.periodic && order == 1) v = v + exact(s.rise) / exact(s.period);
  return v;
}

bool table_covers(const Spline& s, double t) {
  if (s.periodic) return true;
  if (s.t.empty()) return false;
  const double slack = 8 * std::numeric_limits<double>::epsilon() *
                       std::max(std::abs(s.t.front()), std::abs(s.t.back()));
  return t >= s.t.front() - slack && t <= s.t.back() + slack;
}

TableCoverage table_coverage(const Mechanism& m) {
  TableCoverage c;
  for (const Constraint& d : m.drivers) {
    if (d.law.table_id < 0) continue;
    const Spline& s = registered_table(d.law.table_id);
    if (s.periodic) continue;
    c.lo = std::max(c.lo, s.t.front());
    c.hi = std::min(c.hi, s.t.back());
  }
  return c;
}

void check_tables_hold(const Mechanism& m, double t) {
  for (const Constraint& d : m.drivers) {
    if (d.law.table_id < 0) continue;
    const Spline& s = registered_table(d.law.table_id);
    if (table_covers(s, t)) continue;
    throw InputError(m.source, d.item + " table", d.law.table_loc,
                     "table '" + d.law.table + "' does not hold the start, " + format_time(t) +
                         " (its t runs from " + format_number(s.t.front()) + " to " +
                         format_number(s.t.back()) +
                         "; a table is never extrapolated: give it a period or more rows)");
  }
}

std::string table_outside(const Mechanism& m, double t) {
  for (const Constraint& d : m.drivers) {
    if (d.law.table_id < 0) continue;
    const Spline& s = registered_table(d.law.table_id);
    if (table_covers(s, t)) continue;
    return d.item + " table '" + d.law.table + "' (its t runs from " + format_number(s.t.front()) +
           " to " + format_number(s.t.back()) +
           "; a table is never extrapolated: give it a period or more rows)";
  }
  return "";
}

namespace {

// A load's input named `name` given its table: true, or false when there is none.
bool apply_load_input(Mechanism& m, const std::string& name, const std::string& path) {
  for (Load& l : m.forces.loads)
    for (Load::Input& in : l.inputs) {
      if (in.name != name) continue;
      const TableSource src{m.source, l.item + " --input " + name, l.loc, false};
      std::vector<double> t, v;
      read_table(fs::absolute(path).string(), src, t, v);
      in.table_ref = register_table(fit_not_a_knot(t, v), src);
      in.table_id = in.table_ref->id();
      return true;
    }
  return false;
}

}  // namespace

void apply_inputs(Mechanism& m, const std::vector<std::pair<std::string, std::string>>& inputs,
                  bool required, bool free_as_state) {
  std::set<std::string> given;
  for (const auto& [name, path] : inputs) {
    if (!given.insert(name).second) throw UsageError("--input " + name + " is given twice");
    Constraint* driver = nullptr;
    for (Constraint& d : m.drivers)
      if (d.name == name && d.law.input && !(d.free && free_as_state)) driver = &d;
    if (!driver && apply_load_input(m, name, path)) continue;
    if (!driver)
      throw UsageError("--input " + name + ": " + m.source +
                       " has no input driver (f: input) or load input named '" + name + "'" +
                       (free_as_state ? " (a free coordinate's motion is the simulation's)" : ""));
    const TableSource src{m.source, driver->item + " --input " + name, driver->value.loc, false};
    std::vector<double> t, v;
    read_table(fs::absolute(path).string(), src, t, v);
    driver->law.input = false;
    driver->free.reset();  // a free coordinate given its motion is a prescribed driver
    driver->law.table = path;
    const Spline spline = fit_not_a_knot(t, v);
    check_spline(spline, path, src);
    driver->law.table_ref = register_table(spline, src);
    driver->law.table_id = driver->law.table_ref->id();
  }
  if (!required) return;
  for (const Constraint& d : m.drivers) {
    if (d.free && free_as_state) continue;
    if (d.free)
      throw UsageError(d.item +
                       " is a free coordinate, moved by the forces: `kinegen "
                       "simulate` finds its motion; to prescribe it here, give its values with "
                       "--input " +
                       d.name + "=FILE.csv (columns t,value)");
    if (d.law.input)
      throw UsageError(d.item + " is an input driver (f: input): give its values with --input " +
                       d.name + "=FILE.csv (columns t,value)");
  }
  for (const Load& l : m.forces.loads)
    for (const Load::Input& in : l.inputs)
      if (in.table_id < 0)
        throw UsageError(l.item + " has a run-time input: give its values with --input " +
                         in.name + "=FILE.csv (columns t,value)");
}

bool Spline::eval(double x, double* f) const {
  const int n = static_cast<int>(t.size());
  return periodic ? kernels::spline_eval_periodic(t.data(), y.data(), m.data(), n, period, rise,
                                                  x, f)
                  : kernels::spline_eval(t.data(), y.data(), m.data(), n, x, f);
}

void read_table(const std::string& path, const TableSource& src, std::vector<double>& t,
                std::vector<double>& value) {
  const fs::path file = resolve(path, src);
  // Bounded whatever the path names (a device, a FIFO, standard input).
  const FileText text = read_bounded(file.string(), kMaxTableBytes);
  if (!text.ok()) fail(src, text.problem("the table file '" + path + "'", kMaxTableBytes));
  std::istringstream in(text.text);
  std::string line;
  int row = 0;  // 1-based line in the CSV
  bool header = false;
  t.clear();
  value.clear();
  while (std::getline(in, line)) {
    ++row;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;  // blank line
    const auto comma = line.find(',');
    const std::string where = "'" + path + "' line " + std::to_string(row);
    if (comma == std::string::npos || line.find(',', comma + 1) != std::string::npos)
      fail(src, "table " + where + " must have exactly two columns (t,value)");
    double a = 0, b = 0;
    const bool na = parse_number(line.substr(0, comma), a);
    const bool nb = parse_number(line.substr(comma + 1), b);
    if (!header) {  // the first non-blank line names the columns
      if (na && nb)
        fail(src, "table " + where + " must be a header row (for example 't,value')");
      header = true;
      continue;
    }
    if (!na || !nb) fail(src, "table " + where + " is not two numbers");
    if (!std::isfinite(a) || !std::isfinite(b))
      fail(src, "table " + where + " holds a value that is not finite");
    if (!t.empty() && !(a > t.back()))
      fail(src, "table " + where + ": t must increase strictly (" + format_number(a) + " follows " +
                    format_number(t.back()) + ")");
    if (t.size() >= kMaxTableRows)
      fail(src, "table '" + path + "' has more than " + std::to_string(kMaxTableRows) + " rows");
    t.push_back(a);
    value.push_back(b);
  }
  if (!header) fail(src, "the table file '" + path + "' is empty");
  if (t.size() < 4)
    fail(src, "table '" + path + "' has " + std::to_string(t.size()) +
                  " rows; a cubic spline needs at least 4");
}

void check_spline(const Spline& spline, const std::string& path, const TableSource& src) {
  const std::vector<double>& t = spline.t;
  const char* what[3] = {"value", "slope", "second derivative"};
  for (std::size_t k = 0; k < t.size(); ++k) {
    for (const double x : {t[k], k + 1 < t.size() ? t[k] + (t[k + 1] - t[k]) / 2 : t[k]}) {
      double f[3] = {0, 0, 0};
      if (!spline.eval(x, f)) continue;
      for (int o = 0; o < 3; ++o)
        if (!std::isfinite(f[o]))
          fail(src, "table '" + path + "': its spline's " + what[o] +
                        " at t = " + format_number(x) + " is " + format_number(f[o]) +
                        ", beyond a double: values near 1e308, or rows whose t are too close "
                        "for their values' differences (slopes overflow); scale the table");
    }
  }
}

Spline fit_not_a_knot(std::vector<double> t, std::vector<double> y) {
  const int n = static_cast<int>(t.size());
  std::vector<double> h(n - 1);
  for (int i = 0; i + 1 < n; ++i) h[i] = t[i + 1] - t[i];
  std::vector<Eigen::Triplet<double>> a;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
  // Not-a-knot: the third derivative is continuous at t[1] and t[n-2].
  a.emplace_back(0, 0, h[1]);
  a.emplace_back(0, 1, -(h[0] + h[1]));
  a.emplace_back(0, 2, h[0]);
  for (int i = 1; i + 1 < n; ++i) {
    a.emplace_back(i, i - 1, h[i - 1]);
    a.emplace_back(i, i, 2 * (h[i - 1] + h[i]));
    a.emplace_back(i, i + 1, h[i]);
    rhs[i] = 6 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
  }
  a.emplace_back(n - 1, n - 3, h[n - 2]);
  a.emplace_back(n - 1, n - 2, -(h[n - 3] + h[n - 2]));
  a.emplace_back(n - 1, n - 1, h[n - 3]);
  Spline s;
  s.m = solve(a, rhs);
  s.t = std::move(t);
  s.y = std::move(y);
  return s;
}

Spline fit_periodic(std::vector<double> t, std::vector<double> y) {
  const int n = static_cast<int>(t.size());
  const int k = n - 1;  // unknowns m[0..k-1]; m[k] = m[0]
  Spline s;
  s.periodic = true;
  s.period = t.back();
  s.rise = y.back() - y.front();
  for (int i = 0; i < n; ++i) y[i] -= s.rise * (t[i] / s.period);
  y.back() = y.front();  // exactly, whatever the rounding of the trend
  std::vector<double> h(k);
  for (int i = 0; i < k; ++i) h[i] = t[i + 1] - t[i];
  std::vector<Eigen::Triplet<double>> a;
  Eigen::VectorXd rhs(k);
  for (int i = 0; i < k; ++i) {
    const int prev = (i + k - 1) % k;
    const double hp = h[prev], hi = h[i];
    const double yp = i == 0 ? y[k - 1] : y[i - 1];
    a.emplace_back(i, prev, hp);
    a.emplace_back(i, i, 2 * (hp + hi));
    a.emplace_back(i, (i + 1) % k, hi);
    rhs[i] = 6 * ((y[i + 1] - y[i]) / hi - (y[i] - yp) / hp);
  }
  s.m = solve(a, rhs);
  s.m.push_back(s.m.front());
  s.t = std::move(t);
  s.y = std::move(y);
  return s;
}

}  // namespace kinegen::codegen

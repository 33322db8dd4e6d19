// Measured tables for `table:` drivers and `--input` files: reading a two-column
// CSV safely, and fitting the cubic spline that kernels/spline.hpp evaluates.
//
// Takes: a path relative to the mechanism file (or a command-line path), the item that names
// it (for messages) and whether the law is periodic. Gives: a Spline (knots, values, second
// derivatives; for a periodic table also its period and rise). Throws InputError.
#pragma once

#include <ginac/ginac.h>

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/base/diagnostics.hpp"

namespace kinegen::codegen {

struct Spline {
  std::vector<double> t, y, m;  // knots, values (less the trend when periodic), S'' at knots
  bool periodic = false;
  double period = 0;  // periodic: t.back() (t.front() is 0)
  double rise = 0;    // periodic: f(period) - f(0)

  // f[0..2] = value, first and second derivative at x; false outside a non-periodic table.
  bool eval(double x, double* f) const;
};

// The tables of the mechanisms alive in this process, by number (kinegen_table's id in
// functions.hpp). A table belongs to the mechanisms that use it: each holds a TableRef
// (DriverLaw::table_ref, Load::Input::table_ref), and the slot is freed when the last one
// goes, the slot then reused under a new number (a generation tag: a number kept past its
// table's release never reads another table). Registering a spline equal to a live table's
// gives that table's slot. Thread-safe.
class TableSlot {
 public:
  explicit TableSlot(int id) : id_(id) {}
  ~TableSlot();  // frees the slot
  TableSlot(const TableSlot&) = delete;
  TableSlot& operator=(const TableSlot&) = delete;
  int id() const { return id_; }

 private:
  int id_;
};
using TableRef = std::shared_ptr<const TableSlot>;

// At most this many different tables alive at once (equal tables share a slot).
inline constexpr int kMaxTables = 1 << 20;

struct TableSource;
// Throws InputError naming `source` (the file, the item and its line) when kMaxTables
// tables are alive.
TableRef register_table(const Spline& spline, const TableSource& source);
// The table of a live slot, without a lock (a slot's spline is set before its number is
// handed out, and freed only when no mechanism holds it). Throws std::logic_error for a
// number that is not live: one whose table was released, also when its slot holds another.
const Spline& registered_table(int id);
// How many tables are alive (for tests).
int live_tables();

// The order-th derivative (0..2) of a spline at x in CLN arithmetic (the reference), with the
// knots taken exactly; x's precision is kept. Throws AnalysisError outside a table that does
// not repeat.
GiNaC::numeric spline_high_precision(const Spline& s, int order, const GiNaC::numeric& x);

struct Mechanism;
// The times every table of `m`'s drivers covers (those without a period): [lo, hi], and the
// first driver whose table does not hold t (nullptr when all do, or there is none). Tables are
// never extrapolated; the analysis stops at such a t.
struct TableCoverage {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
};
TableCoverage table_coverage(const Mechanism& m);
// Whether a table holds t: periodic, or t within its knots up to a few ulps of its ends.
bool table_covers(const Spline& s, double t);
// InputError naming the first driver whose table does not hold t, the start of a run (its
// table's line and range): the file's fault, not a free item's value0.
void check_tables_hold(const Mechanism& m, double t);
// The driver (its item) whose table does not cover t, with the table's range, or "".
std::string table_outside(const Mechanism& m, double t);

// Turns each named input driver (`f: input`) into a table driver read from its CSV file
// (`analyze --input NAME=FILE.csv`; the path is the user's, relative to the working
// directory, not confined). Throws UsageError for a name that is not an input driver, one
// given twice, or (when `required`) an input driver left without a table. A free coordinate
// given a table becomes a prescribed driver; with free_as_state (simulate and the
// other dynamics commands) the free coordinates are the state and take no table.
void apply_inputs(Mechanism& m, const std::vector<std::pair<std::string, std::string>>& inputs,
                  bool required, bool free_as_state = false);

// Limits that keep a hostile table from costing unbounded time or memory.
inline constexpr std::size_t kMaxTableBytes = 8u << 20;
inline constexpr std::size_t kMaxTableRows = 200000;

struct TableSource {
  std::string mechanism_file;  // the file that names the table (messages; its folder roots it)
  std::string item;            // e.g. "drivers[0] (absolute_angle) table"
  SourceLoc loc;
  bool confine = true;  // refuse a path that leaves the mechanism's folder (by .. or a link)
};

// Reads `path` (two columns, a header row, t strictly increasing, at least 4 rows, finite).
// Returns the columns t and value.
void read_table(const std::string& path, const TableSource& source, std::vector<double>& t,
                std::vector<double>& value);

// The not-a-knot cubic spline through (t, y): reproduces any cubic polynomial exactly.
Spline fit_not_a_knot(std::vector<double> t, std::vector<double> y);

// The periodic spline: t[0] must be 0; the values less their trend (y.back() - y.front()) t / T
// are interpolated by a spline whose value, slope and curvature match across the seam.
Spline fit_periodic(std::vector<double> t, std::vector<double> y);

// Refuses a fitted spline that is not finite (InputError naming the table `path` and the t):
// values near 1e308 or knots 1e-300 apart give slopes and curvatures beyond a double. Checks
// f, f' and f'' at every knot and midway between knots.
void check_spline(const Spline& spline, const std::string& path, const TableSource& source);

}  // namespace kinegen::codegen

// Breakpoints of a simulation (docs/format.md, Simulation): the times where a driver's or a
// load's function of t is not smooth, so that an integrator ends a step there and restarts
// from there instead of stepping across a kink.
//
// Found on the expressions themselves (the rows of Phi, where the drivers' laws are, and Q^A,
// where the loads are), with the parameters' values: every call that is smooth only piecewise
// in its argument g(t), and the values of g where it is not:
//   - a piece boundary or a period seam: kinegen_select(c, ...) at c = 0 (c = t - until, with t
//     wrapped into the period), kinegen_floor(u) at every integer u (u = t / period);
//   - a clamped motion law (cycloidal, harmonic, poly345, poly4567) at x = 0 and x = 1;
//   - a table (a driver's, an input's from --input, a load's) at each knot, repeated every
//     period for a periodic table.
// g is split at its own breakpoints first; on each piece, with every floor and select in it
// fixed to its value there, a g linear in t gives its crossings exactly (t = (level - b) / a,
// in exact arithmetic, rounded once); any other g is sampled at kBreakpointSamples points per
// piece, and each sign change of g - level is bisected to the last bit. So a crossing whose
// excursion starts and ends between two samples (a touch, or two crossings closer than the
// piece's length / kBreakpointSamples) may be missed there.
// A call whose argument depends on the state (q, qd), not on t alone, has state-dependent
// breakpoints (events): not a source of breakpoints() but of state_switches(), for an
// integrator to locate like a stop_when root and restart from. The result may hold times where
// nothing changes (a law inside a piece that is not active then): a restart there costs a step.
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
#include <string>
#include <vector>

namespace kinegen::codegen {

class CompiledModel;
struct ForceModel;

// Samples per smooth piece of an argument that is not linear in t.
inline constexpr int kBreakpointSamples = 256;
// More breakpoints than this in one run is a UsageError (a period far shorter than the run).
inline constexpr std::size_t kMaxBreakpoints = 1000000;

// The values of a call's argument where the call is not smooth: base + k period for every
// integer k (period 0: base alone), base ascending.
struct BreakpointLevels {
  std::vector<double> base;
  double period = 0;
  // The levels in [lo, hi], ascending up to duplicates (UsageError beyond kMaxBreakpoints).
  void within(double lo, double hi, std::vector<double>& out) const;
};

// A non-smooth call whose argument depends on the state: the argument, an expression in q, qd
// and t with the parameters' values, and the levels where the call is not smooth.
struct StateSwitch {
  GiNaC::ex argument;
  BreakpointLevels levels;
};

// Sorted, unique (times closer than a few ulps merged) and strictly inside (t0, t1), away from
// t0 and t1 by more than a few ulps. The loads are those of `forces`; the first overload
// derives them from the model's own force data.
std::vector<double> breakpoints(const CompiledModel& model, double t0, double t1);
std::vector<double> breakpoints(const CompiledModel& model, const ForceModel& forces, double t0,
                                double t1);

// Every non-smooth call of the drivers and loads whose argument depends on the state, once
// each (the press's poly345(depth/ramp): levels 0 and 1 of depth/ramp).
std::vector<StateSwitch> state_switches(const CompiledModel& model, const ForceModel& forces);

// The input table `--input NAME=PATH` (an input driver's, or a load input's)
// covers [t0, t1] (up to a few ulps of its ends): else a UsageError naming the table, its range
// and the run's, before the run (a table is never extrapolated; without this the run fails
// somewhere later, blaming the first thing the table's end breaks). Nothing for another name.
void check_input_coverage(const CompiledModel& model, const std::string& name,
                          const std::string& path, double t0, double t1);
// The same for every input table the model was built with (BuildOptions::inputs): what
// run_simulation and the reference check before they start, for every caller.
void check_input_coverage(const CompiledModel& model, double t0, double t1);

}  // namespace kinegen::codegen

// Position, velocity and acceleration analysis over a time grid, in-process, with the runtime's
// solver on a compiled model; and the CSV form of its rows.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "kinegen/codegen/model.hpp"

namespace kinegen::codegen {

// t_k = t0 + k (t1 - t0) / steps, k = 0..steps (one row at t0 when steps is 0).
struct TimeGrid {
  double t0 = 0, t1 = 0;
  int steps = 0;
  double at(int k) const { return steps == 0 ? t0 : t0 + k * (t1 - t0) / steps; }
};

struct PointState {
  Eigen::Vector2d r, v, a;
};

struct StateRow {
  double t = 0;
  Eigen::VectorXd q, qd, qdd;
  std::vector<PointState> points;
};

// Throws InputError unless the model is kinematically driven (nc == nq).
void require_driven(const CompiledModel& model);

// Solves every time of the grid, handing each row to `sink` as soon as it is solved, so a
// failure keeps what came before. Throws AnalysisError naming the file and time on failure.
void run_analysis(const CompiledModel& model, const TimeGrid& grid,
                  const std::function<void(const StateRow&)>& sink);

// Position, velocity and acceleration of a point at local offset s on a body.
PointState point_state(const Eigen::Vector3d& q, const Eigen::Vector3d& qd,
                       const Eigen::Vector3d& qdd, const Eigen::Vector2d& s);

std::string csv_header(const Mechanism& mechanism);
std::string csv_row(const StateRow& row);
// A double with 17 significant digits.
std::string format_number(double value);

}  // namespace kinegen::codegen

// What the analysis adds for spatial files (docs/format.md, Spatial mechanisms): the first
// solve by continuation of the drivers from the q0 pose, the branch checks after every position
// solve, and the CSV's angular velocities and accelerations, points and vectors in 3D.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

class SpatialAnalysis {
 public:
  explicit SpatialAnalysis(const CompiledModel& model);
  ~SpatialAnalysis();
  SpatialAnalysis(const SpatialAnalysis&) = delete;
  SpatialAnalysis& operator=(const SpatialAnalysis&) = delete;

  // From q (the q0 pose) towards the solution at t: every driver moves from its value at the
  // q0 pose (angle0 for a revolute_angle; the measured value for the others) to f(t) in steps
  // of at most 0.25 rad (or 0.25 of a dot product) or 0.1 of the length scale, each solved by
  // Newton from the previous one. `expression` drivers hold at t throughout. The caller then
  // solves at t. Throws AnalysisError when a step does not converge.
  void first_position(Eigen::VectorXd& q, double t) const;
  // Throws AnalysisError, naming the item and t, when a revolute_angle, a translational lock or
  // the axes of a revolute or cylindrical joint left their branch at q.
  void check_branches(const Eigen::VectorXd& q, double t) const;
  // The columns after t and the bodies' positions, in the CSV's order: per body its velocity,
  // angular velocity omega = 2 E pdot, acceleration and alpha = 2 E pdd (12; global); per point
  // its position, velocity and acceleration (9); per vector the same (9).
  std::vector<double> columns(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                              const Eigen::VectorXd& qdd) const;
  // A row of the CSV (csv_header's columns for a spatial file): t, per body its coordinates
  // and columns() after them, the points', vectors' and outputs' columns, `extra` (a
  // suspension's motion ratios), then the sensitivities when the row has them.
  std::string csv_row(const StateRow& row, const std::vector<double>& extra = {}) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace kinegen::codegen

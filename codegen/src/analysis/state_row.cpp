// What a row of the analysis holds beside q, qd and qdd: points, outputs; and the CSV text of
// rows.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"

namespace kinegen::codegen {

PointState point_state(const Eigen::Vector3d& q, const Eigen::Vector3d& qd,
                       const Eigen::Vector3d& qdd, const Eigen::Vector2d& s) {
  const auto k =
      point_kinematics(q.data(), qd.data(), qdd.data(), std::cos(q[2]), std::sin(q[2]), s[0], s[1]);
  PointState p;
  p.r = {k[0], k[1]};
  p.v = {k[2], k[3]};
  p.a = {k[4], k[5]};
  return p;
}

OutputEvaluator::OutputEvaluator(const CompiledModel& model)
    : nq_(model.nq()),
      n_(model.programs().num_outputs),
      params_(model.params()),
      values_(n_),
      rates_(model.programs().output_rates.outputs.size()),
      reads_velocity_(model.programs().output_reads_velocity),
      value_program_(model.programs().outputs),
      rate_program_(model.programs().output_rates) {}

void OutputEvaluator::evaluate(double t, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                               const Eigen::VectorXd& qdd,
                               std::vector<std::array<double, 3>>& out) {
  out.resize(n_);
  if (n_ == 0) return;
  value_program_.run(q.data(), qd.data(), t, params_.data(), values_.data());
  rate_program_.run(q.data(), qd.data(), t, params_.data(), rates_.data());
  assemble_outputs(reads_velocity_, nq_, values_.data(), rates_.data(), qdd.data(),
                   std::numeric_limits<double>::quiet_NaN(), out);
}

// Spatial files (docs/format.md, Spatial mechanisms): the bodies' seven coordinates and their
// linear and angular rates, points and vectors in 3D.
std::string spatial_csv_header(const Mechanism& m) {
  std::string h = "t";
  const auto add = [&](const std::string& name, std::initializer_list<const char*> columns) {
    for (const char* c : columns) h += "," + name + "." + c;
  };
  for (const auto& b : m.bodies)
    add(b.name, {"x", "y", "z", "e0", "e1", "e2", "e3", "vx", "vy", "vz", "wx", "wy", "wz", "ax",
                 "ay", "az", "alphax", "alphay", "alphaz"});
  for (const auto* list : {&m.points, &m.vectors})
    for (const auto& p : *list)
      add(p.name, {"x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az"});
  for (const auto& o : m.outputs) h += "," + o.name + "," + o.name + ".v," + o.name + ".a";
  return h + "\n";
}

std::string csv_header(const Mechanism& m) {
  if (m.spatial) return spatial_csv_header(m);
  std::string h = "t";
  for (const auto& b : m.bodies)
    for (const char* c : {"x", "y", "phi", "vx", "vy", "omega", "ax", "ay", "alpha"})
      h += "," + b.name + "." + c;
  for (const auto& q : m.coordinates) h += "," + q.name + "," + q.name + ".v," + q.name + ".a";
  for (const auto& p : m.points)
    for (const char* c : {"x", "y", "vx", "vy", "ax", "ay"}) h += "," + p.name + "." + c;
  for (const auto& o : m.outputs) h += "," + o.name + "," + o.name + ".v," + o.name + ".a";
  return h + "\n";
}

std::string csv_header(const Mechanism& m, const std::vector<std::string>& sensitivity) {
  return csv_header(m, {}, sensitivity);
}

std::string csv_header(const Mechanism& m, const std::vector<std::string>& forces,
                       const std::vector<std::string>& sensitivity) {
  std::string h = csv_header(m);
  h.pop_back();  // the line break
  for (const auto& c : forces) h += "," + c;
  for (const auto& c : sensitivity_columns(m, sensitivity)) h += "," + c;
  return h + "\n";
}

std::string csv_row(const StateRow& row, int num_bodies) {
  std::string s = format_number(row.t);
  for (int b = 0; b < num_bodies; ++b) {
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.q[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qd[3 * b + c]);
    for (int c = 0; c < 3; ++c) s += "," + format_number(row.qdd[3 * b + c]);
  }
  for (int k = 3 * num_bodies; k < row.q.size(); ++k)  // extra coordinates
    s += "," + format_number(row.q[k]) + "," + format_number(row.qd[k]) + "," +
         format_number(row.qdd[k]);
  for (const auto& p : row.points)
    for (const Eigen::Vector2d* v : {&p.r, &p.v, &p.a})
      s += "," + format_number((*v)[0]) + "," + format_number((*v)[1]);
  for (const auto& o : row.outputs)
    for (double v : o) s += "," + format_number(v);
  for (double f : row.forces) s += "," + format_number(f);
  // Sensitivities: per parameter, every coordinate (the bodies' x, y, phi, the extra ones),
  // the points' x, y, the outputs, as sensitivity_columns names them.
  for (int k = 0; k < row.dq_dp.cols(); ++k) {
    for (int i = 0; i < row.dq_dp.rows(); ++i) s += "," + format_number(row.dq_dp(i, k));
    for (int i = 0; i < row.dpoints_dp.rows(); ++i) s += "," + format_number(row.dpoints_dp(i, k));
    for (int i = 0; i < row.doutputs_dp.rows(); ++i)
      s += "," + format_number(row.doutputs_dp(i, k));
  }
  return s + "\n";
}

}  // namespace kinegen::codegen

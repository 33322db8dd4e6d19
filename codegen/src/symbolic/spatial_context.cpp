// Spatial files (docs/format.md, Spatial mechanisms): a body's q0 from its pose (p normalized),
// and EquationContext's 3-vector view: frames of Euler parameters, A(p) in its homogeneous
// form, d_ij and the q0 pose in numbers for the vectors carried into a body there.
#include <cctype>
#include <cmath>
#include <string>
#include <vector>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "symbolic_detail.hpp"

namespace kinegen::codegen {

using GiNaC::ex;

namespace symbolic_detail {

std::vector<ex> spatial_q0(const Mechanism& m, const SymbolTable& s,
                           const std::vector<GiNaC::numeric>& values, int body) {
  const Body& b = m.bodies[body];
  const std::string item = "body '" + b.name + "'";
  const auto number = [&](const ex& e) { return to_double(substitute_params(e, s, values)); };
  std::vector<ex> q;
  for (const Expr& e : b.pose.r0) q.push_back(geometry_value(m, s, values, e, item + " r0"));
  std::vector<ex> p;
  if (!b.pose.p0.empty()) {
    for (const Expr& e : b.pose.p0) p.push_back(geometry_value(m, s, values, e, item + " p0"));
  } else {
    std::vector<ex> axis;
    for (const Expr& e : b.pose.axis)
      axis.push_back(geometry_value(m, s, values, e, item + " rot0 axis"));
    const ex length2 = axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2];
    if (!(std::sqrt(number(length2)) >= 1e-12))
      throw InputError(m.source, item, b.pose.rotation_loc, "the rot0 axis must not be zero");
    const ex half = geometry_value(m, s, values, b.pose.angle, item + " rot0 angle") / 2;
    p = {GiNaC::cos(half)};
    for (const ex& a : axis) p.push_back(GiNaC::sin(half) * a / GiNaC::sqrt(length2));
  }
  const ex norm2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3];
  const double norm = std::sqrt(number(norm2));
  if (!(norm >= 1e-12) || !std::isfinite(norm))
    throw InputError(m.source, item, b.pose.rotation_loc,
                     "the Euler parameters' length is " + format_number(norm) +
                         "; it must be a finite number of at least 1e-12 (they are normalized)");
  for (const ex& e : p) q.push_back(e / GiNaC::sqrt(norm2));
  return q;
}

void define_spatial_names(const Mechanism& m, SymbolTable& s, const SymbolicModel& model) {
  const auto frame = [&](int body) {
    std::array<ex, 4> p;
    for (int k = 0; k < 4; ++k) p[k] = s.q(7 * body + 3 + k);
    return p;
  };
  const char* const kAxes[] = {"x", "y", "z"};
  for (std::size_t k = 0; k < m.points.size(); ++k) {
    const auto& v = model.point_s3[k];
    const int b = m.points[k].body;
    const auto a = EquationContext::rotate3(frame(b), {v[0], v[1], v[2]});
    for (int c = 0; c < 3; ++c)
      s.define(m.points[k].name + "__" + kAxes[c], s.q(7 * b + c) + a[c]);
  }
  for (std::size_t k = 0; k < m.vectors.size(); ++k) {
    const auto& v = model.vectors3[k];
    const auto a = EquationContext::rotate3(frame(m.vectors[k].body), {v[0], v[1], v[2]});
    for (int c = 0; c < 3; ++c) s.define(m.vectors[k].name + "__" + kAxes[c], a[c]);
  }
}

Expr spatial_output_text(const Mechanism& m, const Expr& e) {
  Expr out = e;
  std::string& t = out.text;
  const auto word = [&](std::size_t at) {
    return at < t.size() && (std::isalnum(static_cast<unsigned char>(t[at])) || t[at] == '_');
  };
  for (const auto* list : {&m.points, &m.vectors})
    for (const Point& p : *list)
      for (std::size_t at = t.find(p.name + "."); at != std::string::npos;
           at = t.find(p.name + ".", at + 1)) {
        const std::size_t axis = at + p.name.size() + 1;
        if ((at > 0 && word(at - 1)) || axis >= t.size() || word(axis + 1) ||
            (t[axis] != 'x' && t[axis] != 'y' && t[axis] != 'z'))
          continue;
        t.replace(at + p.name.size(), 1, "__");
      }
  return out;
}

}  // namespace symbolic_detail

using namespace symbolic_detail;

EquationContext::Frame3 EquationContext::frame3(int body) const {
  if (body == kGround) return {{0, 0, 0}, {1, 0, 0, 0}};
  const int k = 7 * body;
  return {{s_.q(k), s_.q(k + 1), s_.q(k + 2)},
          {s_.q(k + 3), s_.q(k + 4), s_.q(k + 5), s_.q(k + 6)}};
}

EquationContext::Vec3 EquationContext::rotate3(const std::array<ex, 4>& p, const Vec3& v) {
  const ex& e0 = p[0];
  const Vec3 e{p[1], p[2], p[3]};
  const ex ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
  const ex ev = e[0] * v[0] + e[1] * v[1] + e[2] * v[2];
  const Vec3 exv{e[1] * v[2] - e[2] * v[1], e[2] * v[0] - e[0] * v[2], e[0] * v[1] - e[1] * v[0]};
  Vec3 out;
  for (int k = 0; k < 3; ++k) out[k] = (e0 * e0 - ee) * v[k] + 2 * e[k] * ev + 2 * e0 * exv[k];
  return out;
}

EquationContext::Vec3 EquationContext::vector3(const std::string& key) const {
  const Vec2& v = c_.vector(key);
  const std::string item = c_.item + " " + key;
  return {geometry(v.x, item), geometry(v.y, item), geometry(v.z, item)};
}

EquationContext::Vec3 EquationContext::d_ij3() const { return d_ij3(vector3("si"), vector3("sj")); }

EquationContext::Vec3 EquationContext::d_ij3(const Vec3& si, const Vec3& sj) const {
  const Frame3 fi = frame3(c_.i), fj = frame3(c_.j);
  const Vec3 ai = rotate3(fi.p, si), aj = rotate3(fj.p, sj);
  Vec3 d;
  for (int k = 0; k < 3; ++k) d[k] = fj.r[k] + aj[k] - fi.r[k] - ai[k];
  return d;
}

Eigen::Matrix3d EquationContext::rotation0(int body) const {
  if (body == kGround) return Eigen::Matrix3d::Identity();
  const std::vector<ex> q = spatial_q0(m_, s_, values_, body);
  std::array<ex, 4> p;
  for (int k = 0; k < 4; ++k) p[k] = q[3 + k];
  Eigen::Matrix3d a;
  for (int col = 0; col < 3; ++col) {
    Vec3 unit{0, 0, 0};
    unit[col] = 1;
    const Vec3 v = rotate3(p, unit);
    for (int row = 0; row < 3; ++row) a(row, col) = number(v[row]);
  }
  return a;
}

Eigen::Vector3d EquationContext::origin0(int body) const {
  if (body == kGround) return Eigen::Vector3d::Zero();
  const std::vector<ex> q = spatial_q0(m_, s_, values_, body);
  return {number(q[0]), number(q[1]), number(q[2])};
}

EquationContext EquationContext::joint_context() const {
  if (c_.joint < 0) throw std::logic_error(c_.item + " has no joint key");
  return EquationContext(m_.joints[c_.joint], m_, s_, values_);
}

}  // namespace kinegen::codegen

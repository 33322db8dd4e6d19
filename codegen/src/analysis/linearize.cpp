// Linear models for control and the operating point's syntax (see analysis/linearize.hpp).
#include "kinegen/codegen/analysis/linearize.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "kinegen/codegen/base/format.hpp"

namespace kinegen::codegen {

std::vector<std::string> state_names(const Mechanism& m) {
  std::vector<std::string> names;
  for (int d : m.free_drivers()) names.push_back(m.drivers[d].name);
  for (int d : m.free_drivers()) names.push_back(m.drivers[d].name + ".v");
  return names;
}

std::vector<std::string> input_names(const Mechanism& m) {
  std::vector<std::string> names;
  for (const RunInput& in : run_inputs(m)) names.push_back(in.name);
  return names;
}

namespace {

double number_of(const std::string& text, const std::string& option) {
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(begin, &end);
  if (text.empty() || end != begin + text.size() || !std::isfinite(v))
    throw UsageError(option + ": '" + text + "' is not a finite number");
  return v;
}

std::string list(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

// Where a name given one value goes: a vector key and an index in it.
struct Target {
  std::string key;
  int index = 0;
};

}  // namespace

OperatingPoint parse_operating_point(const Mechanism& m, const std::string& text,
                                     const std::vector<std::string>& keys, OperatingPoint base,
                                     const std::string& option) {
  const auto allowed = [&](const std::string& k) {
    return std::find(keys.begin(), keys.end(), k) != keys.end();
  };
  const std::vector<std::string> free = state_names(m), inputs = input_names(m);
  const int nf = static_cast<int>(free.size()) / 2;
  std::vector<std::pair<std::string, Target>> names;  // one value each
  if (allowed("z"))
    for (int k = 0; k < nf; ++k) names.push_back({free[k], {"z", k}});
  if (allowed("zd"))
    for (int k = 0; k < nf; ++k) {
      names.push_back({free[nf + k], {"zd", k}});
      names.push_back({free[k] + "_d", {"zd", k}});
    }
  if (allowed("u"))
    for (std::size_t k = 0; k < inputs.size(); ++k)
      names.push_back({inputs[k], {"u", static_cast<int>(k)}});
  const auto vector_of = [&](const std::string& key) -> Eigen::VectorXd& {
    return key == "z" ? base.z : key == "zd" ? base.zd : base.u;
  };
  const auto what = [&](const std::string& key) {
    return key == "u" ? "one per run-time input (" + list(inputs) + ")"
                      : "one per free coordinate (" + list({free.begin(), free.begin() + nf}) + ")";
  };
  std::vector<std::string> items;
  for (std::size_t b = 0, e; !text.empty() && b <= text.size(); b = e + 1) {
    e = std::min(text.find(',', b), text.size());
    items.push_back(text.substr(b, e - b));
  }
  for (std::size_t i = 0; i < items.size();) {
    const std::size_t eq = items[i].find('=');
    if (eq == std::string::npos)
      throw UsageError(option + " expects KEY=VALUE items separated by commas, not '" + items[i] +
                       "'");
    const std::string key = items[i].substr(0, eq);
    std::vector<std::string> values{items[i].substr(eq + 1)};
    for (++i; i < items.size() && items[i].find('=') == std::string::npos; ++i)
      values.push_back(items[i]);
    if (key == "t" && allowed("t")) {
      if (values.size() != 1)
        throw UsageError(option + " t expects one value, got " + std::to_string(values.size()));
      base.t = number_of(values[0], option + " t");
    } else if ((key == "z" || key == "zd" || key == "u") && allowed(key)) {
      Eigen::VectorXd& v = vector_of(key);
      if (static_cast<Eigen::Index>(values.size()) != v.size() &&
          !(v.size() == 0 && values.size() == 1 && values[0].empty()))
        throw UsageError(option + " " + key + " expects " + std::to_string(v.size()) + " value" +
                         (v.size() == 1 ? "" : "s") + ", " + what(key) + ", got " +
                         std::to_string(values.size()));
      for (Eigen::Index k = 0; k < v.size(); ++k) v[k] = number_of(values[k], option + " " + key);
    } else {
      const auto it =
          std::find_if(names.begin(), names.end(), [&](const auto& n) { return n.first == key; });
      if (it == names.end()) {
        std::vector<std::string> known;
        for (const char* k : {"t", "z", "zd", "u"})
          if (allowed(k)) known.push_back(k);
        for (const auto& n : names) known.push_back(n.first);
        throw UsageError(option + ": unknown name '" + key + "' (known: " + list(known) + ")");
      }
      if (values.size() != 1)
        throw UsageError(option + " " + key + " expects one value, got " +
                         std::to_string(values.size()));
      vector_of(it->second.key)[it->second.index] = number_of(values[0], option + " " + key);
    }
  }
  return base;
}

LinearModel linearize(Linearizer& linearizer, const OperatingPoint& p) {
  const Mechanism& m = linearizer.model().mechanism();
  LinearModel out;
  out.at = p;
  out.states = state_names(m);
  out.inputs = input_names(m);
  Eigen::MatrixXd d_z, d_zd, d_u;
  if (!linearizer.evaluate(p, out.state, &d_z, &d_zd, &d_u))
    throw AnalysisError(m.source + ": cannot linearize at " + format_time(p.t) + ": " +
                        linearizer.reason());
  const int nf = linearizer.nf(), nu = linearizer.nu();
  out.x.resize(2 * nf);
  out.x << p.z, p.zd;
  out.xdot.resize(2 * nf);
  out.xdot << p.zd, out.state.zdd;
  out.a = Eigen::MatrixXd::Zero(2 * nf, 2 * nf);
  out.a.topRightCorner(nf, nf).setIdentity();
  out.a.bottomLeftCorner(nf, nf) = d_z;
  out.a.bottomRightCorner(nf, nf) = d_zd;
  out.b = Eigen::MatrixXd::Zero(2 * nf, nu);
  // A block of an empty matrix offsets its null data pointer (undefined behaviour that clang's
  // UBSan reports): no inputs, no block.
  if (nu > 0) out.b.bottomRows(nf) = d_u;
  return out;
}

}  // namespace kinegen::codegen

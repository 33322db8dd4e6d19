// The `stop_when:` expression, whose crossing of 0 from below ends a simulation.
// It may name the CSV's columns (B.x, P.vy, J.fn), which the expression language has no
// syntax for: each such column is rewritten to a name of its own (`B__x`; "__" is never a
// user's name) and defined for this one parse.
#include "kinegen/codegen/symbolic/stop_when.hpp"

#include <cctype>
#include <map>
#include <set>

#include "kinegen/codegen/symbolic/symbolic.hpp"

namespace kinegen::codegen {

namespace {

using GiNaC::ex;

ex time_derivative(const ex& e, const SymbolTable& s) {
  ex d = 0;
  for (int k = 0; k < s.nq(); ++k) d += e.diff(s.q(k)) * s.qd(k);
  return d;
}

// Whether e holds a derivative GiNaC could not write out (a function without one).
bool has_unknown_derivative(const ex& e) {
  if (GiNaC::is_a<GiNaC::fderivative>(e)) return true;
  for (std::size_t k = 0; k < e.nops(); ++k)
    if (has_unknown_derivative(e.op(k))) return true;
  return false;
}

// Kept as ex: a copy into GiNaC::symbol would slice a coordinate's realsymbol, which the symbol
// table then no longer knows (and the rate would silently fall back to differences).
void collect_symbols(const ex& e, std::vector<ex>& out) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) {
    for (const auto& known : out)
      if (known.is_equal(e)) return;
    out.push_back(e);
  }
  for (std::size_t k = 0; k < e.nops(); ++k) collect_symbols(e.op(k), out);
}

std::string alias(const std::string& column) {
  std::string a = column;
  for (std::size_t p = a.find('.'); p != std::string::npos; p = a.find('.', p))
    a.replace(p, 1, "__");
  return a;
}

// Every column stop_when may name, as an expression (force columns are extra parameters that
// the simulation supplies, not here); the rates it may not name go to no_rate.
std::map<std::string, ex> stop_when_columns(const Mechanism& m, SymbolTable& s,
                                            const SymbolicModel& model,
                                            std::set<std::string>& no_rate) {
  std::map<std::string, ex> columns;
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const std::string& n = m.bodies[b].name;
    const char* const kPos[] = {".x", ".y", ".phi"};
    const char* const kVel[] = {".vx", ".vy", ".omega"};
    for (int c = 0; c < 3; ++c) {
      columns[n + kPos[c]] = s.q(static_cast<int>(3 * b) + c);
      columns[n + kVel[c]] = s.qd(static_cast<int>(3 * b) + c);
    }
  }
  for (std::size_t p = 0; p < m.points.size(); ++p) {
    const int b = 3 * m.points[p].body;
    const ex& sx = model.point_s[p].first;
    const ex& sy = model.point_s[p].second;
    const ex phi = s.q(b + 2);
    const ex x = s.q(b) + cos(phi) * sx - sin(phi) * sy;
    const ex y = s.q(b + 1) + sin(phi) * sx + cos(phi) * sy;
    const std::string& n = m.points[p].name;
    columns[n + ".x"] = x;
    columns[n + ".y"] = y;
    columns[n + ".vx"] = time_derivative(x, s);
    columns[n + ".vy"] = time_derivative(y, s);
  }
  const std::vector<int> free = m.free_drivers();
  for (std::size_t k = 0; k < free.size(); ++k)
    columns[m.drivers[free[k]].name + ".v"] = model.free_rates[k];
  // An output that reads velocities has a rate that reads the accelerations, which
  // stop_when cannot: its NAME.v is refused (derive_stop_when).
  for (std::size_t o = 0; o < m.outputs.size(); ++o) {
    columns[m.outputs[o].name] = model.output_values[o];
    if (model.output_reads_velocity[o])
      no_rate.insert(m.outputs[o].name + ".v");
    else
      columns[m.outputs[o].name + ".v"] = model.output_rates[o];
  }
  return columns;
}

}  // namespace

void derive_stop_when(const Mechanism& m, SymbolTable& s, SymbolicModel& model,
                      const std::vector<std::string>& force_columns) {
  if (!m.stop_when) return;
  std::set<std::string> no_rate;
  const std::map<std::string, ex> columns = stop_when_columns(m, s, model, no_rate);
  // Rewrite the columns the text names (the longest match at each place), and define them.
  const std::string& text = m.stop_when->text;
  std::string rewritten;
  std::map<std::string, int> force_index;
  std::map<std::string, bool> defined;
  for (std::size_t k = 0; k < force_columns.size(); ++k)
    force_index[force_columns[k]] = static_cast<int>(k);
  const auto name_char = [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.';
  };
  for (std::size_t k = 0; k < text.size();) {
    if (!name_char(text[k]) || (k > 0 && name_char(text[k - 1]))) {
      rewritten += text[k++];
      continue;
    }
    std::size_t end = k;
    while (end < text.size() && name_char(text[end])) ++end;
    const std::string token = text.substr(k, end - k);
    if (token.find('.') != std::string::npos &&
        !std::isdigit(static_cast<unsigned char>(token[0]))) {
      if (defined[token]) {
      } else if (const auto f = force_index.find(token); f != force_index.end()) {
        s.define_extra(alias(token));
        model.stop_force_columns.push_back(f->second);
      } else if (const auto c = columns.find(token); c != columns.end()) {
        s.define(alias(token), c->second);
      } else if (no_rate.count(token)) {
        throw InputError(m.source, "stop_when", m.stop_when->loc,
                         "'" + token +
                             "' is the rate of an output that reads velocities, which needs "
                             "the accelerations; stop_when may use the output itself");
      } else {
        throw InputError(m.source, "stop_when", m.stop_when->loc,
                         "'" + token +
                             "' is not a column of the simulation (body, point, free, output "
                             "or force columns: B.x, P.vy, Z.v, J.fn, D.effort, ...)");
      }
      defined[token] = true;
      rewritten += alias(token);
    } else {
      if (const auto c = columns.find(token);
          c != columns.end() && token.find('.') == std::string::npos)
        s.define(token, c->second);  // an output by its name
      rewritten += token;
    }
    k = end;
  }
  model.stop_when = s.parse(Expr{rewritten, m.stop_when->loc}, Scope::kLoad, "stop_when");
}

std::vector<GiNaC::ex> stop_when_rate(const SymbolicModel& model, const SymbolTable& s) {
  const ex& g = model.stop_when;
  try {
    // The force columns' symbols, in stop_force_columns order: the extra parameters.
    std::vector<ex> symbols;
    collect_symbols(g, symbols);
    std::vector<ex> forces(model.stop_force_columns.size(), ex(0));
    for (const ex& symbol : symbols) {
      const Input in = s.classify(symbol);
      const int extra = in.index - s.num_params();
      if (in.kind == InputKind::kParam && extra >= 0 && extra < static_cast<int>(forces.size()))
        forces[extra] = symbol;
    }
    std::vector<ex> d_qd, d_q;
    ex rate0 = g.diff(s.t());
    for (int k = 0; k < s.nq(); ++k) {
      d_qd.push_back(g.diff(s.qd(k)));
      d_q.push_back(g.diff(s.q(k)));
      rate0 += d_q.back() * s.qd(k);
    }
    std::vector<ex> pieces{rate0};
    pieces.insert(pieces.end(), d_qd.begin(), d_qd.end());
    pieces.insert(pieces.end(), d_q.begin(), d_q.end());
    for (const ex& f : forces)
      pieces.push_back(GiNaC::is_a<GiNaC::symbol>(f) ? g.diff(GiNaC::ex_to<GiNaC::symbol>(f))
                                                     : ex(0));
    for (const ex& p : pieces)
      if (has_unknown_derivative(p)) return {};
    return pieces;
  } catch (const std::exception&) {
    return {};  // a function without a derivative: the simulation uses differences
  }
}

}  // namespace kinegen::codegen

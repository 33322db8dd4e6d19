// The scene of `kinegen view`'s page: animate's drawing (animate_drawing) as JSON, each element
// named by the body or constraint behind it and linked to the run's columns about it.
#include <cmath>
#include <cstdio>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/symbolic/forces.hpp"
#include "view_json.hpp"

namespace kinegen::codegen::view {

void Json::separate() {
  if (first_.empty()) return;
  if (!first_.back()) out_ += ',';
  first_.back() = false;
}

Json& Json::key(const std::string& name) {
  separate();
  string(name);
  out_ += ':';
  return *this;
}

Json& Json::item() {
  separate();
  return *this;
}

Json& Json::string(const std::string& value) {
  out_ += '"';
  for (const char ch : value) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out_ += '\\';
      out_ += ch;
    } else if (ch == '<' || ch == '>' || ch == '&' || u < 0x20) {
      char buffer[8];
      std::snprintf(buffer, sizeof buffer, "\\u%04x", u);
      out_ += buffer;
    } else {
      out_ += ch;
    }
  }
  out_ += '"';
  return *this;
}

Json& Json::number(double value) {
  out_ += std::isfinite(value) ? format_number(value) : "null";
  return *this;
}

Json& Json::vec(const Eigen::Vector2d& v) {
  out_ += '[';
  number(v[0]);
  out_ += ',';
  number(v[1]);
  out_ += ']';
  return *this;
}

Json& Json::open(char bracket) {
  out_ += bracket;
  first_.push_back(true);
  return *this;
}

Json& Json::close(char bracket) {
  out_ += bracket;
  first_.pop_back();
  return *this;
}

int Columns::find(const std::string& name) const {
  for (std::size_t k = 0; k < names_.size(); ++k)
    if (names_[k] == name) return static_cast<int>(k);
  return -1;
}

std::vector<int> Columns::group(const std::string& base,
                                const std::vector<const char*>& suffixes) const {
  std::vector<int> out;
  for (const char* s : suffixes)
    if (const int k = find(base + s); k >= 0) out.push_back(k);
  return out;
}

namespace {

void ints(Json& json, const std::string& name, const std::vector<int>& values) {
  json.key(name).open('[');
  for (int v : values) json.item().raw(std::to_string(v));
  json.close(']');
}

void attach(Json& json, const Attach& a) {
  json.key("body").raw(std::to_string(a.body)).key("s").vec(a.s);
}

// How the page names a constraint: its name and its item ("sun_mesh: joints[3] (gear)").
std::string title(const Constraint* c) {
  if (!c) return "";
  return c->name.empty() ? c->item : c->name + ": " + c->item;
}

void guide(Json& json, const AnimateDrawing::Guide& g, const Constraint* by) {
  json.item().open('{');
  attach(json, g.point);
  json.key("guide").raw(std::to_string(g.guide)).key("origin").vec(g.origin).key("dir").vec(g.dir);
  json.key("travel").open('[').item().number(g.travel_min).item().number(g.travel_max).close(']');
  json.key("name").string(title(by)).close('}');
}

// The reaction arrows: every joint whose J.fx and J.fy the run has, at the point of the body
// the columns report (body j unless it is ground), as animate --forces draws them.
void reactions(Json& json, const CompiledModel& model, const Columns& columns) {
  const Mechanism& m = model.mechanism();
  const std::vector<std::string> names = force_columns(m);
  int reacting = 0;
  const auto count = [](const Constraint& c) {
    return is_expression(c) ? 0 : 3 + static_cast<int>(c.kind->normal_force);
  };
  for (const Constraint& c : m.joints) reacting += count(c);
  std::size_t column = names.size() - static_cast<std::size_t>(reacting);
  json.key("reactions").open('[');
  for (const Constraint& c : m.joints) {
    if (is_expression(c)) continue;
    const std::string base = names[column].substr(0, names[column].size() - 3);  // less ".fx"
    column += static_cast<std::size_t>(count(c));
    const int fx = columns.find(base + ".fx"), fy = columns.find(base + ".fy");
    if (fx < 0 || fy < 0) continue;
    const bool on_j = c.j != kGround;
    const Vec2 s = reaction_point(c, on_j ? c.kind->reaction_j : c.kind->reaction_i);
    const Eigen::Vector2d at(model.geometry_number(s.x, c.item),
                             model.geometry_number(s.y, c.item));
    json.item().open('{').key("body").raw(std::to_string(on_j ? c.j : c.i)).key("s").vec(at);
    json.key("name").string(title(&c)).key("fx").raw(std::to_string(fx));
    json.key("fy").raw(std::to_string(fy));
    ints(json, "columns", columns.group(base, {".fx", ".fy", ".tz", ".fn"}));
    json.close('}');
  }
  json.close(']');
}

}  // namespace

void write_scene(Json& json, const CompiledModel& model, const AnimateDrawing& d,
                 const Columns& columns) {
  const Mechanism& m = model.mechanism();
  json.key("bodies").open('[');
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const std::string& name = m.bodies[b].name;
    json.item().open('{').key("name").string(name).key("outline").open('[');
    for (const auto& p : d.bodies[b]) json.item().vec(p);
    json.close(']');
    ints(json, "columns",
         columns.group(name, {".x", ".y", ".phi", ".vx", ".vy", ".omega", ".ax", ".ay", ".alpha"}));
    json.close('}');
  }
  json.close(']').key("pins").open('[');
  for (std::size_t k = 0; k < d.pins.size(); ++k) {
    json.item().open('{');
    attach(json, d.pins[k]);
    json.key("name").string(title(d.pin_by[k])).close('}');
  }
  json.close(']').key("ground_pivots").open('[');
  for (const auto& g : d.ground_pivots) json.item().vec(g);
  json.close(']').key("sliders").open('[');
  for (std::size_t k = 0; k < d.sliders.size(); ++k) guide(json, d.sliders[k], d.slider_by[k]);
  json.close(']').key("pitch_lines").open('[');
  for (std::size_t k = 0; k < d.pitch_lines.size(); ++k)
    guide(json, d.pitch_lines[k], d.line_by[k]);
  json.close(']').key("struts").open('[');
  for (std::size_t k = 0; k < d.struts.size(); ++k) {
    json.item().open('{').key("a").open('{');
    attach(json, d.struts[k].first);
    json.close('}').key("b").open('{');
    attach(json, d.struts[k].second);
    json.close('}').key("name").string(title(d.strut_by[k])).close('}');
  }
  json.close(']').key("pitch_circles").open('[');
  for (std::size_t k = 0; k < d.pitch_circles.size(); ++k) {
    json.item().open('{');
    attach(json, d.pitch_circles[k].centre);
    json.key("radius").number(d.pitch_circles[k].radius);
    json.key("name").string(title(d.circle_by[k])).close('}');
  }
  json.close(']').key("welds").open('[');
  for (std::size_t k = 0; k < d.welds.size(); ++k) {
    json.item().open('{');
    attach(json, d.welds[k]);
    json.key("name").string(title(d.weld_by[k])).close('}');
  }
  json.close(']').key("curves").open('[');
  for (std::size_t k = 0; k < d.curves.size(); ++k) {
    json.item().open('{').key("body").raw(std::to_string(d.curves[k].body)).key("points").open('[');
    for (const auto& p : d.curves[k].points) json.item().vec(p);
    json.close(']').key("name").string(title(d.curve_by[k])).close('}');
  }
  json.close(']').key("points").open('[');
  for (std::size_t k = 0; k < d.points.size(); ++k) {
    json.item().open('{');
    attach(json, d.points[k]);
    json.key("name").string(m.points[k].name);
    ints(json, "columns",
         columns.group(m.points[k].name, {".x", ".y", ".vx", ".vy", ".ax", ".ay"}));
    json.close('}');
  }
  json.close(']').key("springs").open('[');
  for (const auto& sp : d.springs) {
    json.item().open('{').key("a").open('{');
    attach(json, sp.a);
    json.close('}').key("b").open('{');
    attach(json, sp.b);
    json.close('}').key("spring").raw(sp.spring ? "true" : "false");
    json.key("damper").raw(sp.damper ? "true" : "false");
    json.key("rotational").raw(sp.rotational ? "true" : "false");
    json.key("name").string(sp.name).close('}');
  }
  json.close(']').key("loads").open('[');
  for (const auto& l : d.loads) {
    json.item().open('{');
    attach(json, l.at);
    json.key("dir").vec(l.dir).key("torque").raw(l.torque ? "true" : "false");
    json.key("name").string(l.name).close('}');
  }
  json.close(']');
  reactions(json, model, columns);
  json.key("view").open('{');
  for (const auto& [name, v] : {std::pair<const char*, double>{"scale", d.scale},
                                {"x0", d.x0},
                                {"y0", d.y0},
                                {"width", d.width},
                                {"height", d.height},
                                {"margin", d.margin},
                                {"title", d.title}})
    json.key(name).number(v);
  json.close('}').key("colours").open('{');
  for (const auto& [role, colour] : d.colours) json.key(role).string(colour);
  json.close('}');
}

}  // namespace kinegen::codegen::view

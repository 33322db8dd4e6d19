// Reads a mechanism file into plain data and validates its structure: keys, types, names,
// references and vector lengths. Expressions stay text; the symbolic stage parses them.
#include "kinegen/codegen/model/mechanism.hpp"

#include "loader.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <stdexcept>
#include <unordered_set>

#include "kinegen/codegen/base/format.hpp"
#include "kinegen/codegen/base/read_file.hpp"
#include "kinegen/codegen/constraints/registry.hpp"
#include "kinegen/codegen/model/table.hpp"
#include "kinegen/codegen/symbolic/functions.hpp"

namespace kinegen::codegen {

namespace {

// C++ keywords and alternative tokens (C++20), which a name must not be.
const std::unordered_set<std::string>& cpp_keywords() {
  static const std::unordered_set<std::string> kKeywords = {
      "alignas",   "alignof",      "and",          "and_eq",      "asm",
      "auto",      "bitand",       "bitor",        "bool",        "break",
      "case",      "catch",        "char",         "char8_t",     "char16_t",
      "char32_t",  "class",        "compl",        "concept",     "const",
      "consteval", "constexpr",    "constinit",    "const_cast",  "continue",
      "co_await",  "co_return",    "co_yield",     "decltype",    "default",
      "delete",    "do",           "double",       "dynamic_cast", "else",
      "enum",      "explicit",     "export",       "extern",      "false",
      "float",     "for",          "friend",       "goto",        "if",
      "inline",    "int",          "long",         "mutable",     "namespace",
      "new",       "noexcept",     "not",          "not_eq",      "nullptr",
      "operator",  "or",           "or_eq",        "private",     "protected",
      "public",    "register",     "reinterpret_cast", "requires", "return",
      "short",     "signed",       "sizeof",       "static",      "static_assert",
      "static_cast", "struct",     "switch",       "template",    "this",
      "thread_local", "throw",     "true",         "try",         "typedef",
      "typeid",    "typename",     "union",        "unsigned",    "using",
      "virtual",   "void",         "volatile",     "wchar_t",     "while",
      "xor",       "xor_eq",       "final",        "override",    "import",
      "module"};
  return kKeywords;
}

}  // namespace

using model_detail::kMaxFileSize;
using model_detail::Loader;

const char* Constraint::type_name() const { return kind ? kind->name : "?"; }

int Constraint::equation_count() const {
  return kind->rows > 0 ? kind->rows : static_cast<int>(equations.size());
}

const Vec2& Constraint::vector(const std::string& key) const {
  const auto it = vectors.find(key);
  if (it == vectors.end()) throw std::logic_error(item + " has no vector key '" + key + "'");
  return it->second;
}

int Mechanism::nc() const {
  int n = 0;
  for (const auto* c : constraints()) n += c->equation_count();
  return n;
}

std::vector<const Constraint*> Mechanism::constraints() const {
  std::vector<const Constraint*> all;
  for (const auto& c : joints) all.push_back(&c);
  for (const auto& c : drivers) all.push_back(&c);
  for (const auto& c : normalization) all.push_back(&c);
  return all;
}

std::vector<int> Mechanism::free_drivers() const {
  std::vector<int> out;
  for (std::size_t k = 0; k < drivers.size(); ++k)
    if (drivers[k].free) out.push_back(static_cast<int>(k));
  return out;
}

std::vector<const Load::Input*> Mechanism::load_inputs() const {
  std::vector<const Load::Input*> out;
  for (const Load& l : forces.loads)
    for (const Load::Input& in : l.inputs) out.push_back(&in);
  return out;
}

std::vector<RunInput> run_inputs(const Mechanism& m) {
  std::vector<RunInput> out;
  for (std::size_t d = 0; d < m.drivers.size(); ++d) {
    const Constraint& c = m.drivers[d];
    if (!c.law.input || c.free) continue;
    const int slot = 3 * static_cast<int>(d);
    out.push_back({c.name, slot});
    out.push_back({c.name + "_v", slot + 1});
    out.push_back({c.name + "_a", slot + 2});
  }
  const int nd = static_cast<int>(m.drivers.size());
  for (const Load::Input* in : m.load_inputs())
    if (in->table_id < 0) out.push_back({in->name, 3 * (nd + in->index)});
  return out;
}

std::optional<int> Mechanism::find_body(const std::string& name) const {
  for (std::size_t k = 0; k < bodies.size(); ++k)
    if (bodies[k].name == name) return static_cast<int>(k);
  return std::nullopt;
}

bool is_valid_identifier(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  if (!(std::isalpha(static_cast<unsigned char>(name[0])))) return false;  // also rules out '_X'
  for (char ch : name)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_')) return false;
  if (name.find("__") != std::string::npos) return false;
  return cpp_keywords().count(name) == 0;
}

namespace {

// Line `line` (0-based) of `text`, its end's blanks removed, shortened to 80 characters and
// its control characters shown as '?' ("" for a blank or absent line).
std::string line_text(const std::string& text, int line) {
  std::size_t begin = 0;
  for (int k = 0; k < line; ++k) {
    begin = text.find('\n', begin);
    if (begin == std::string::npos) return "";
    ++begin;
  }
  std::string shown = text.substr(begin, text.find('\n', begin) - begin);
  while (!shown.empty() && (shown.back() == '\r' || shown.back() == ' ')) shown.pop_back();
  if (shown.find_first_not_of(" \t") == std::string::npos) return "";
  constexpr std::size_t kShown = 80;
  if (shown.size() > kShown) shown = shown.substr(0, kShown) + "...";
  for (char& ch : shown)
    if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) ch = '?';
  return shown;
}

// What a YAML syntax error at (line, column) (0-based) adds to the parser's message: the line
// it names, and where a flow bracket ('[' or '{') still open there was opened, since the
// parser notices a missing ']' or '}' only lines later.
std::string syntax_context(const std::string& text, int line, int column) {
  std::string out;
  if (const std::string here = line_text(text, line); !here.empty())
    out = " in the line: \"" + here + "\"";
  struct Open {
    char bracket;
    int line;
  };
  std::vector<Open> open;
  char quote = 0;
  char before = '\n';  // the last character other than a blank, outside quotes
  int l = 0, c = 0;
  for (std::size_t k = 0; k < text.size() && (l < line || (l == line && c < column)); ++k) {
    const char ch = text[k];
    if (ch == '\n') {
      ++l;
      c = 0;
      before = '\n';
      continue;
    }
    ++c;
    if (quote) {
      if (ch == quote) quote = 0;
      continue;
    }
    if (ch == ' ' || ch == '\t') continue;
    if (ch == '#' && (k == 0 || text[k - 1] == ' ' || text[k - 1] == '\t' || before == '\n')) {
      k = std::min(text.find('\n', k), text.size()) - 1;  // a comment: to the line's end
      continue;
    }
    // A quote opens a quoted scalar only where a scalar starts (not in "it's").
    const bool starts = before == '\n' || before == ':' || before == ',' || before == '[' ||
                        before == '{' || before == '-';
    before = ch;
    if ((ch == '"' || ch == '\'') && starts) {
      quote = ch;
    } else if (ch == '[' || ch == '{') {
      open.push_back({ch, l});
    } else if ((ch == ']' || ch == '}') && !open.empty()) {
      open.pop_back();
    }
  }
  if (!open.empty() && open.back().line != line)
    out += "; the '" + std::string(1, open.back().bracket) + "' opened at line " +
           std::to_string(open.back().line + 1) + " is not closed: \"" +
           line_text(text, open.back().line) + "\"";
  return out;
}

}  // namespace

Mechanism parse_mechanism(const std::string& yaml_text, const std::string& source) {
  if (yaml_text.size() > kMaxFileSize)
    throw InputError(source, "file", {},
                     "the file is larger than " + std::to_string(kMaxFileSize) +
                         " bytes; a mechanism file is far smaller");
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw InputError(source, "YAML syntax", {e.mark.line + 1, e.mark.column + 1},
                     e.msg + syntax_context(yaml_text, e.mark.line, e.mark.column));
  }
  return Loader(source).load(root);
}

Mechanism load_mechanism(const std::string& path) {
  // Bounded whatever the path names (a device, a FIFO, standard input): parse_mechanism's
  // limit, applied while reading.
  const FileText file = read_bounded(path, kMaxFileSize);
  if (!file.ok()) {
    std::string problem = file.problem("the mechanism file", kMaxFileSize);
    if (file.status == FileText::Status::kTooLarge) problem += "; a mechanism file is far smaller";
    throw InputError(path, "file", {}, problem);
  }
  return parse_mechanism(file.text, path);
}

std::vector<std::string> coordinate_labels(const Mechanism& m) {
  std::vector<std::string> labels;
  for (const auto& b : m.bodies) {
    if (m.spatial)
      for (const char* c : {".x", ".y", ".z", ".e0", ".e1", ".e2", ".e3"})
        labels.push_back(b.name + c);
    else
      for (const char* c : {".x", ".y", ".phi"}) labels.push_back(b.name + c);
  }
  for (const auto& c : m.coordinates) labels.push_back(c.name);
  return labels;
}

}  // namespace kinegen::codegen

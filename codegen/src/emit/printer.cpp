#include "printer.hpp"

namespace kinegen::codegen::emit_detail {

// Integers that double (and T(int) for float, through double) holds exactly.
bool is_small_integer(const GiNaC::numeric& x) {
  return x.is_integer() && GiNaC::abs(x) <= GiNaC::numeric(1L << 53);
}

std::string str(const GiNaC::numeric& x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

std::string safe_comment_text(const std::string& s) {
  std::string out;
  for (char ch : s)
    out += (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '-' ||
            ch == '+')
               ? ch
               : '?';
  return out;
}

// The Params members of input driver k (`f: input`): its value, rate and acceleration,
// NAME, NAME_v and NAME_a.
std::string input_member(const Mechanism& m, int driver, int order) {
  static const char* const kSuffix[] = {"", "_v", "_a"};
  const int nd = static_cast<int>(m.drivers.size());
  if (driver >= nd)  // a load's input (Load::Input): slots after the drivers', its value only
    return m.load_inputs().at(static_cast<std::size_t>(driver - nd))->name + kSuffix[order];
  return m.drivers.at(static_cast<std::size_t>(driver)).name + kSuffix[order];
}

// The members FunctionPrinter wrote as `T(p.@inK.O@)`, named. A free item's is read
// through _free_in, which dynamics() points at its z, zd and zdd in the scalar type, so
// that a complex z reaches the solves (Params holds doubles).
std::string with_input_members(std::string header, const Mechanism& m) {
  const std::vector<int> free = m.free_drivers();
  const int nf = static_cast<int>(free.size());
  for (std::size_t p = header.find("p.@in"); p != std::string::npos; p = header.find("p.@in", p)) {
    const std::size_t dot = header.find('.', p + 5), end = header.find('@', p + 5);
    const int driver = std::stoi(header.substr(p + 5, dot - p - 5));
    const int order = std::stoi(header.substr(dot + 1, end - dot - 1));
    const std::string member = input_member(m, driver, order);
    const auto it = std::find(free.begin(), free.end(), driver);
    const bool wrapped = p >= 2 && header.compare(p - 2, 2, "T(") == 0 &&
                         header.compare(end + 1, 1, ")") == 0;
    if (it != free.end() && wrapped) {
      const int slot = order * nf + static_cast<int>(it - free.begin());
      const std::string read = "_free_in<T>(p, " + std::to_string(slot) + ", p." + member + ")";
      header.replace(p - 2, end + 2 - (p - 2), read);
      p = p - 2 + read.size();
    } else {
      header.replace(p + 2, end + 1 - (p + 2), member);
    }
  }
  return header;
}

// A table's function as FunctionPrinter writes it, `_tbl@ID@` (ID its registry number), until
// with_expression_kernels numbers the tables of the header from 0.
std::string table_token(int id) { return "_tbl@" + std::to_string(id) + "@"; }

// The std functions a program calls, for a using-declaration: unqualified calls then find
// std's overloads for float, double and std::complex, and other scalar types by ADL.
std::string std_functions(const Program& program) {
  static const std::pair<OpKind, const char*> kFunctions[] = {
      {OpKind::kAcos, "acos"}, {OpKind::kAsin, "asin"}, {OpKind::kAtan, "atan"},
      {OpKind::kCos, "cos"},   {OpKind::kExp, "exp"},   {OpKind::kLog, "log"},
      {OpKind::kPow, "pow"},   {OpKind::kSin, "sin"},   {OpKind::kSqrt, "sqrt"},
      {OpKind::kTan, "tan"}};
  std::string used;
  for (const auto& [kind, fname] : kFunctions) {
    bool uses = false;
    for (const auto& n : program.nodes)
      uses = uses || n.kind == kind ||
             (kind == OpKind::kPow && n.kind == OpKind::kPowInt &&
              std::abs(n.exponent) > kMaxUnrolledPower);
    if (uses) used += std::string(used.empty() ? "" : ", ") + "std::" + fname;
  }
  return used;
}

// Splits `program` into parts of about max_ops operations or max_part_outputs outputs each
// (partition.hpp; one output's terms are never split).

void emit_signature(std::ostringstream& os, const std::string& name, bool with_qd) {
  os << "  template <class T>\n";
  os << "  static void " << name << "([[maybe_unused]] const T* q,";
  if (with_qd) os << " [[maybe_unused]] const T* qd,";
  os << "\n      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* out) noexcept {\n";
}

// One function, or when the program has more than max_ops operations or max_part_outputs
// outputs (max_ops > 0), private parts that the function calls in order: g++ -O2 takes time
// superlinear in a function's size.
// out_index: the out index of each of the program's outputs (default: k); tail: code that ends
// the public function.
void emit_function(std::ostringstream& os, const char* name, const char* out_size,
                   const Program& program, const SymbolTable& symbols, bool with_qd,
                   int max_ops, const std::vector<int>* out_index, const std::string& tail) {
  if (split_function(program, max_ops)) {
    const std::vector<ProgramPart> parts = split_program(program, max_ops);
    os << " private:\n";
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const Program& part = parts[k].program;
      const int last = parts[k].first_output + static_cast<int>(part.outputs.size()) - 1;
      emit_signature(os, "_" + std::string(name) + "_part" + std::to_string(k), with_qd);
      if (out_index)
        os << "    // outputs " << parts[k].first_output << ".." << last << " of the "
           << program.outputs.size() << " not repeated; " << part.operation_count()
           << " operations\n";
      else
        os << "    // out[" << parts[k].first_output << ".." << last << "]; "
           << part.operation_count() << " operations\n";
      if (const std::string used = std_functions(part); !used.empty())
        os << "    using " << used << ";\n";
      os << FunctionPrinter(part, symbols).body("    ", parts[k].first_output, out_index);
      os << "  }\n";
    }
    os << "\n public:\n";
    emit_signature(os, name, with_qd);
    os << "    // out[" << out_size << "]; " << program.operation_count() << " operations in "
       << parts.size() << " parts\n";
    for (std::size_t k = 0; k < parts.size(); ++k)
      os << "    _" << name << "_part" << k << "(q, " << (with_qd ? "qd, " : "") << "t, p, out);\n";
    os << tail << "  }\n";
    return;
  }
  os << "  template <class T>\n";
  os << "  static void " << name << "([[maybe_unused]] const T* q,";
  if (with_qd) os << " [[maybe_unused]] const T* qd,";
  os << "\n      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* out) noexcept {\n";
  os << "    // out[" << out_size << "]; " << program.operation_count() << " operations\n";
  if (const std::string used = std_functions(program); !used.empty())
    os << "    using " << used << ";\n";
  os << FunctionPrinter(program, symbols).body("    ", 0, out_index);
  os << tail << "  }\n";
}

// Repeated pieces (blocks, constraints) are compared under a renaming of the coordinates they
// read: the k-th coordinate of a piece's table becomes the model's k-th.

// `static constexpr int name[rows][columns]`, a table of the repeated pieces (a row of zero
// columns is stored as one 0, which nothing reads).
void emit_table(std::ostringstream& os, const std::string& name,
                const std::vector<std::vector<int>>& rows) {
  os << "  static constexpr int " << name << "[" << rows.size() << "]["
     << std::max<std::size_t>(1, rows[0].size()) << "] = {\n";
  for (const auto& row : rows) {
    std::vector<std::string> v;
    for (int x : row) v.push_back(std::to_string(x));
    os << "      {" << (v.empty() ? "0" : join(v)) << "},\n";
  }
  os << "  };\n";
}


// emit_function for outputs of which some are rolled (roll_outputs): each class's function and
// tables (private), then the function, which evaluates the rest and loops over the classes.
void emit_rolled_function(std::ostringstream& os, const char* name, const char* out_size,
                          const RolledOutputs& ro, const SymbolTable& symbols, bool with_qd,
                          int max_ops) {
  os << " private:\n";
  std::ostringstream tail;
  for (std::size_t g = 0; g < ro.classes.size(); ++g) {
    const RolledOutputs::Class& c = ro.classes[g];
    const std::string f = "_" + std::string(name) + "_roll" + std::to_string(g);
    os << "  // Repeated constraints (" << c.outs.size() << "): alike up to the coordinates they "
       << "read (" << f << "_i,\n  // ascending) and where their outputs go (" << f << "_o).\n";
    emit_table(os, f + "_i", c.coords);
    emit_table(os, f + "_o", c.outs);
    os << "  template <class T>\n"
       << "  static void " << f << "([[maybe_unused]] const T* q,"
       << (with_qd ? " [[maybe_unused]] const T* qd," : "") << "\n"
       << "      [[maybe_unused]] T t, [[maybe_unused]] const Params& p, T* out,\n"
       << "      [[maybe_unused]] const int* _i, const int* _o) noexcept {\n";
    if (const std::string used = std_functions(c.program); !used.empty())
      os << "    using " << used << ";\n";
    FunctionPrinter pr(c.program, symbols);
    pr.read_through(&c.slot);
    os << pr.body("    ", 0, nullptr, true) << "  }\n";
    tail << "    for (int _m = 0; _m < " << c.outs.size() << "; ++_m)\n"
         << "      " << f << "(q, " << (with_qd ? "qd, " : "") << "t, p, out, " << f << "_i[_m], "
         << f << "_o[_m]);\n";
  }
  os << "\n public:\n";
  emit_function(os, name, out_size, ro.rest, symbols, with_qd, max_ops, &ro.rest_index,
                tail.str());
}

// emit_function, or emit_rolled_function when some constraints repeat (roll_min > 0).
void emit_function_rolled_if(std::ostringstream& os, const char* name, const char* out_size,
                             const Program& program, const std::vector<GiNaC::ex>& exprs,
                             const std::vector<int>& group, const SymbolTable& symbols,
                             bool with_qd, int max_ops, int roll_min) {
  if (roll_min > 0) {
    const RolledOutputs ro = roll_outputs(exprs, group, symbols, roll_min);
    if (!ro.classes.empty()) {
      emit_rolled_function(os, name, out_size, ro, symbols, with_qd, max_ops);
      return;
    }
  }
  emit_function(os, name, out_size, program, symbols, with_qd, max_ops);
}

}  // namespace kinegen::codegen::emit_detail

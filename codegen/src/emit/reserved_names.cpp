// The one list of names a generated header cannot carry. Three kinds:
//  - what the emitter declares in the model's struct, or uses there unqualified: a struct of
//    the same name is ill-formed (a member may not share its class's name) or hides it;
//  - namespaces the header or the runtime name (std, kinegen, models, Solver);
//  - macros: of the C and C++ standard libraries, of POSIX and glibc headers that the standard
//    headers pull in, and the platform macros GNU modes predefine (linux, unix). A macro
//    replaces the name wherever it appears, so it breaks model names and parameters alike.
// tests/test_cli_safety.cpp checks the list against every name the emitter declares at struct
// scope and every macro the compiler defines after including the standard headers.
#include "kinegen/codegen/emit/reserved_names.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <unordered_set>

#include "kinegen/codegen/base/diagnostics.hpp"

namespace kinegen::codegen {

namespace {

// Members, types and helpers of the generated struct (emit_cpp.cpp), and the runtime's names
// that a model's struct would shadow. Keep in step with the emitter; the test above fails
// when it declares a name missing here.
const std::vector<std::string> kHeaderMembers = {
    // every header (docs/format.md, Generated code and the runtime)
    "nq", "nc", "jac_nnz", "jac_rows", "jac_cols", "q0", "Params", "phi", "phi_q", "nu", "gamma",
    "length_scale", "has_velocity", "has_acceleration", "coordinate_kinds", "coordinate_scales",
    // the block solver
    "has_block_solver", "num_blocks", "num_explicit_blocks", "max_block_size", "max_newton_size",
    "num_newton_coordinates", "newton_coordinates", "trig_cache_size", "BlockOptions",
    "BlockReport", "kRotateLimit", "solve_position", "solve_velocity", "solve_acceleration",
    "solve_velocity_acceleration", "solve_step",
    // the structure tables of the linear block solves (emit_structure_tables)
    "block_begin", "block_rows", "block_cols", "coordinate_block", "coordinate_slot",
    "jac_row_begin", "block_factor_begin",
    // spatial files: branch conditions and the drivers' continuation (emit_spatial)
    "num_branches", "num_continued", "continued_rows", "continued_steps", "continued_first",
    "continued_count",
    // forward dynamics (emit_dynamics)
    "has_dynamics", "nf", "num_bodies", "free_names", "free_rows", "free_distance", "free_scale",
    "DynamicsWork", "dynamics", "has_dynamics_jacobians", "num_inputs", "input_names", "JacobianWork",
    "dynamics_jacobians", "step_rk4", "step_implicit",
    // parameter sensitivities (emit_sensitivity)
    "num_params", "has_sensitivity", "phi_p", "sensitivity_work_size", "solve_sensitivity",
    // kinetostatics (emit_forces) and outputs (emit_outputs)
    "has_forces", "num_force_columns", "force_column_names", "applied_force", "generalized_force",
    "solve_forces", "force_columns", "num_outputs", "output_values", "output_rates", "outputs",
    // the step's factors for solve_forces (emit_step_factors)
    "StepFactors", "factor_begin", "step_factored", "block_tears", "tear_rows", "tear_cols",
    "tear_sens_begin",
    // the kernels (runtime/include/kinegen/kernels/) pasted into the struct
    "BasicBlockOptions", "BasicTrigCache", "TrigCache", "kRoundingUlps", "kLinearRatio",
    "kLinearSteps",
    // namespaces and the runtime's Solver, which a struct of that name would hide
    "Solver", "models", "kinegen", "std"};

// Namespaces a --namespace may not use (the standard's own).
const std::unordered_set<std::string> kNamespaces = {"std", "posix"};

// Macros of the C and C++ standard libraries and of the POSIX and glibc headers they include
// (g++ -dM -E on every standard header, gnu++17 and c++20, families with a common prefix
// left to kMacroPrefixes), and the platform macros GCC and Clang predefine in GNU modes.
const std::unordered_set<std::string> kMacros = {
    "AIO_PRIO_DELTA_MAX", "BIG_ENDIAN", "BOOL_MAX", "BOOL_WIDTH", "BUFSIZ", "BYTE_ORDER",
    "CHARCLASS_NAME_MAX", "CHAR_BIT", "CHAR_MAX", "CHAR_MIN", "CHAR_WIDTH", "CLOCKS_PER_SEC",
    "CLOSE_RANGE_CLOEXEC", "CLOSE_RANGE_UNSHARE", "COLL_WEIGHTS_MAX", "CSIGNAL", "DECIMAL_DIG",
    "DELAYTIMER_MAX", "E2BIG", "EACCES", "EADDRINUSE", "EADDRNOTAVAIL", "EADV", "EAFNOSUPPORT",
    "EAGAIN", "EALREADY", "EBADE", "EBADF", "EBADFD", "EBADMSG", "EBADR", "EBADRQC", "EBADSLT",
    "EBFONT", "EBUSY", "ECANCELED", "ECHILD", "ECHRNG", "ECOMM", "ECONNABORTED", "ECONNREFUSED",
    "ECONNRESET", "EDEADLK", "EDEADLOCK", "EDESTADDRREQ", "EDOM", "EDOTDOT", "EDQUOT", "EEXIST",
    "EFAULT", "EFBIG", "EHOSTDOWN", "EHOSTUNREACH", "EHWPOISON", "EIDRM", "EILSEQ", "EINPROGRESS",
    "EINTR", "EINVAL", "EIO", "EISCONN", "EISDIR", "EISNAM", "EKEYEXPIRED", "EKEYREJECTED",
    "EKEYREVOKED", "EL2HLT", "EL2NSYNC", "EL3HLT", "EL3RST", "ELIBACC", "ELIBBAD", "ELIBEXEC",
    "ELIBMAX", "ELIBSCN", "ELNRNG", "ELOOP", "EMEDIUMTYPE", "EMFILE", "EMLINK", "EMSGSIZE",
    "EMULTIHOP", "ENAMETOOLONG", "ENAVAIL", "ENETDOWN", "ENETRESET", "ENETUNREACH", "ENFILE",
    "ENOANO", "ENOBUFS", "ENOCSI", "ENODATA", "ENODEV", "ENOENT", "ENOEXEC", "ENOKEY", "ENOLCK",
    "ENOLINK", "ENOMEDIUM", "ENOMEM", "ENOMSG", "ENONET", "ENOPKG", "ENOPROTOOPT", "ENOSPC",
    "ENOSR", "ENOSTR", "ENOSYS", "ENOTBLK", "ENOTCONN", "ENOTDIR", "ENOTEMPTY", "ENOTNAM",
    "ENOTRECOVERABLE", "ENOTSOCK", "ENOTSUP", "ENOTTY", "ENOTUNIQ", "ENXIO", "EOF", "EOPNOTSUPP",
    "EOVERFLOW", "EOWNERDEAD", "EPERM", "EPFNOSUPPORT", "EPIPE", "EPROTO", "EPROTONOSUPPORT",
    "EPROTOTYPE", "ERANGE", "EREMCHG", "EREMOTE", "EREMOTEIO", "ERESTART", "ERFKILL", "EROFS",
    "ESHUTDOWN", "ESOCKTNOSUPPORT", "ESPIPE", "ESRCH", "ESRMNT", "ESTALE", "ESTRPIPE", "ETIME",
    "ETIMEDOUT", "ETOOMANYREFS", "ETXTBSY", "EUCLEAN", "EUNATCH", "EUSERS", "EWOULDBLOCK", "EXDEV",
    "EXFULL", "EXIT_FAILURE", "EXIT_SUCCESS", "EXPR_NEST_MAX", "FD_CLR", "FD_ISSET", "FD_SET",
    "FD_SETSIZE", "FD_ZERO", "FILENAME_MAX", "FOPEN_MAX", "F_LOCK", "F_OK", "F_TEST", "F_TLOCK",
    "F_ULOCK", "HOST_NAME_MAX", "INFINITY", "IOV_MAX", "ITIMER_PROF", "ITIMER_REAL",
    "ITIMER_VIRTUAL", "LINE_MAX", "LITTLE_ENDIAN", "LLONG_MAX", "LLONG_MIN", "LLONG_WIDTH",
    "LOGIN_NAME_MAX", "LONG_BIT", "LONG_LONG_MAX", "LONG_LONG_MIN", "LONG_MAX", "LONG_MIN",
    "LONG_WIDTH", "L_INCR", "L_SET", "L_XTND", "L_ctermid", "L_cuserid", "L_tmpnam",
    "MATH_ERREXCEPT", "MATH_ERRNO", "MAXFLOAT", "MAX_CANON", "MAX_INPUT", "MB_CUR_MAX",
    "MB_LEN_MAX", "MINSIGSTKSZ", "MQ_PRIO_MAX", "NAME_MAX", "NAN", "NFDBITS", "NGREG",
    "NGROUPS_MAX", "NSIG", "NULL", "NZERO", "PATH_MAX", "PDP_ENDIAN", "PIPE_BUF", "PTRDIFF_MAX",
    "PTRDIFF_MIN", "PTRDIFF_WIDTH", "P_tmpdir", "RAND_MAX", "RENAME_EXCHANGE", "RENAME_NOREPLACE",
    "RENAME_WHITEOUT", "RE_DUP_MAX", "RTSIG_MAX", "R_OK", "SCHAR_MAX", "SCHAR_MIN", "SCHAR_WIDTH",
    "SEEK_CUR", "SEEK_DATA", "SEEK_END", "SEEK_HOLE", "SEEK_SET", "SEM_FAILED", "SEM_VALUE_MAX",
    "SHRT_MAX", "SHRT_MIN", "SHRT_WIDTH", "SIGABRT", "SIGALRM", "SIGBUS", "SIGCHLD", "SIGCLD",
    "SIGCONT", "SIGFPE", "SIGHUP", "SIGILL", "SIGINT", "SIGIO", "SIGIOT", "SIGKILL", "SIGPIPE",
    "SIGPOLL", "SIGPROF", "SIGPWR", "SIGQUIT", "SIGRTMAX", "SIGRTMIN", "SIGSEGV", "SIGSTKFLT",
    "SIGSTKSZ", "SIGSTOP", "SIGSYS", "SIGTERM", "SIGTRAP", "SIGTSTP", "SIGTTIN", "SIGTTOU",
    "SIGURG", "SIGUSR1", "SIGUSR2", "SIGVTALRM", "SIGWINCH", "SIGXCPU", "SIGXFSZ", "SIZE_MAX",
    "SIZE_WIDTH", "SSIZE_MAX", "STDERR_FILENO", "STDIN_FILENO", "STDOUT_FILENO",
    "TEMP_FAILURE_RETRY", "TIMER_ABSTIME", "TIMESPEC_TO_TIMEVAL", "TIMEVAL_TO_TIMESPEC", "TIME_UTC",
    "TMP_MAX", "TTY_NAME_MAX", "UCHAR_MAX", "UCHAR_WIDTH", "ULLONG_MAX", "ULLONG_WIDTH",
    "ULONG_LONG_MAX", "ULONG_MAX", "ULONG_WIDTH", "USHRT_MAX", "USHRT_WIDTH", "WCHAR_MAX",
    "WCHAR_MIN", "WCHAR_WIDTH", "WCONTINUED", "WEOF", "WEXITED", "WEXITSTATUS", "WIFCONTINUED",
    "WIFEXITED", "WIFSIGNALED", "WIFSTOPPED", "WINT_MAX", "WINT_MIN", "WINT_WIDTH", "WNOHANG",
    "WNOWAIT", "WORD_BIT", "WSTOPPED", "WSTOPSIG", "WTERMSIG", "WUNTRACED", "W_OK", "X_OK",
    "alloca", "assert", "assert_perror", "be16toh", "be32toh", "be64toh", "errno", "htobe16",
    "htobe32", "htobe64", "htole16", "htole32", "htole64", "issubnormal", "le16toh", "le32toh",
    "le64toh", "linux", "math_errhandling", "offsetof", "pthread_cleanup_pop",
    "pthread_cleanup_pop_restore_np", "pthread_cleanup_push", "pthread_cleanup_push_defer_np",
    "sa_handler", "sa_sigaction", "sched_priority", "setjmp", "sigev_notify_attributes",
    "sigev_notify_function", "sigmask", "sigsetjmp", "stderr", "stdin", "stdout", "strdupa",
    "strndupa", "timeradd", "timerclear", "timercmp", "timerisset", "timersub", "unix", "va_arg",
    "va_copy", "va_end", "va_start",
    // other systems' predefined macros, and C's keyword macros
    "unix", "linux", "i386", "i486", "i586", "i686", "sun", "sparc", "mips", "vax", "hppa", "pdp11",
    "m68k", "mc68000", "ns32000", "sgi", "u370", "u3b", "u3b2", "u3b5", "ibm032", "interdata",
    "tahoe", "pyr", "complex", "imaginary", "noreturn", "bool", "true", "false", "static_assert",
    "alignas", "alignof", "thread_local", "I"};

// Families of macros with a common prefix (all contain '_', so user names rarely meet them).
constexpr const char* kMacroPrefixes[] = {
    "SYS_",  "PTHREAD_", "CLONE_", "CPU_", "REG_",   "SCHED_", "CLOCK_", "ADJ_",    "MOD_",
    "STA_",  "SEGV_",    "TRAP_",  "SI_",  "si_",    "FPE_",   "ILL_",   "BUS_",    "CLD_",
    "POLL_", "LC_",      "FE_",    "FP_",  "DBL_",   "FLT_",   "LDBL_",  "ATOMIC_", "HUGE_VAL",
    "SNAN",  "SA_",      "SS_",    "SIG_", "SIGEV_", "XATTR_", "NL_",    "BC_"};

// <cmath>'s M_PI family, with the f, l, f32 ... f128x variants glibc adds.
bool math_constant(const std::string& n) {
  if (n.rfind("M_", 0) != 0) return false;
  std::string base = n.substr(2);
  for (const char* suffix : {"f128", "f32x", "f64x", "f32", "f64", "f", "l"}) {
    const std::string s = suffix;
    if (base.size() > s.size() && base.compare(base.size() - s.size(), s.size(), s) == 0) {
      base.resize(base.size() - s.size());
      break;
    }
  }
  for (const char* c : {"E", "LOG2E", "LOG10E", "LN2", "LN10", "PI", "PI_2", "PI_4", "1_PI", "2_PI",
                        "2_SQRTPI", "SQRT2", "SQRT1_2"})
    if (base == c) return true;
  return false;
}

// <cinttypes> format macros (PRId64, SCNxPTR) and <cstdint> limits (INT_FAST8_MAX, UINT16_C).
bool integer_macro(const std::string& n) {
  if ((n.rfind("PRI", 0) == 0 || n.rfind("SCN", 0) == 0) && n.size() > 3 &&
      std::string("diouxX").find(n[3]) != std::string::npos)
    return true;
  const bool int_type = n.rfind("INT", 0) == 0 || n.rfind("UINT", 0) == 0;
  if (!int_type) return false;
  for (const char* suffix : {"_MAX", "_MIN", "_C", "_WIDTH"}) {
    const std::string s = suffix;
    if (n.size() > s.size() && n.compare(n.size() - s.size(), s.size(), s) == 0) return true;
  }
  return false;
}

bool is_macro(const std::string& name) {
  if (kMacros.count(name) || integer_macro(name) || math_constant(name)) return true;
  for (const char* prefix : kMacroPrefixes)
    if (name.rfind(prefix, 0) == 0) return true;
  return false;
}

}  // namespace

const std::vector<std::string>& header_member_names() { return kHeaderMembers; }

std::string header_name_conflict(const std::string& name, HeaderName where) {
  if (is_macro(name))
    return "'" + name +
           "' is a macro of the C or C++ standard library or of the platform, so "
           "the generated header could not use it";
  if (where == HeaderName::kModel &&
      std::find(kHeaderMembers.begin(), kHeaderMembers.end(), name) != kHeaderMembers.end())
    return "'" + name +
           "' is a member or helper name of the generated header (or a namespace "
           "it uses), so a model of that name would not compile";
  if (where == HeaderName::kParameter && name == "Params")
    return "'Params' is the struct that holds the parameters in the generated header";
  return {};
}

void check_header_names(const Mechanism& m) {
  const auto refuse = [&](const std::string& item, SourceLoc loc, const std::string& why) {
    throw InputError(m.source, item, loc,
                     why + "; rename it to generate code (analyze, eval and check accept it)");
  };
  if (auto why = header_name_conflict(m.name, HeaderName::kModel); !why.empty())
    refuse("name", m.name_loc, why);
  // Every member of Params, with the item that declares it: the parameters, an input or free
  // driver's NAME, NAME_v, NAME_a, and a load input's name (a torque's NAME, a force's NAME_x
  // and NAME_y). Two items may derive the same member (a free `x` and a free `x_a`; a free
  // `push_x` and a force `push`), which the loader cannot see because the items live in
  // different namespaces there; the header would not compile.
  struct Owner {
    std::string item;
    SourceLoc loc;
  };
  std::map<std::string, Owner> members;
  const auto declare = [&](const std::string& member, const std::string& item, SourceLoc loc,
                           bool derived) {
    const std::string what = derived ? "its Params member '" + member + "'" : "";
    if (auto why = header_name_conflict(member, HeaderName::kParameter); !why.empty())
      refuse(item, loc, derived ? what + ": " + why : why);
    const auto [it, fresh] = members.emplace(member, Owner{item, loc});
    if (fresh || it->second.item == item) return;
    const Owner& first = it->second;
    refuse(item, loc,
           (derived ? what : "the Params member '" + member + "'") + " is also the Params member " +
               "of " + first.item +
               (first.loc.line > 0 ? " (line " + std::to_string(first.loc.line) + ")" : "") +
               ", so the generated header would declare it twice");
  };
  for (const auto& p : m.parameters) declare(p.name, "parameters." + p.name, p.loc, false);
  // An input driver's Params members (docs/format.md, drivers): NAME, NAME_v, NAME_a; a free
  // item is kept among the drivers as one.
  for (const auto& d : m.drivers) {
    if (!d.law.input) continue;
    for (const char* suffix : {"", "_v", "_a"}) declare(d.name + suffix, d.item, d.loc, true);
  }
  for (const auto& load : m.forces.loads)
    for (const auto& in : load.inputs)
      if (in.table_id < 0) declare(in.name, load.item, load.loc, true);
}

std::string namespace_conflict(const std::string& ns) {
  if (ns.empty()) return "the namespace must not be empty";
  std::size_t from = 0;
  for (;;) {
    const std::size_t sep = ns.find("::", from);
    const std::string part =
        ns.substr(from, sep == std::string::npos ? std::string::npos : sep - from);
    if (!is_valid_identifier(part))
      return "'" + ns +
             "' is not a C++ namespace name (names separated by '::', each a C "
             "identifier that is not a keyword and does not start with '_' or contain '__')";
    if (kNamespaces.count(part)) return "'" + part + "' is reserved for the standard library";
    if (is_macro(part)) return "'" + part + "' is a macro of the C or C++ standard library";
    if (sep == std::string::npos) return {};
    from = sep + 2;
  }
}

}  // namespace kinegen::codegen

// Names a generated header cannot carry: the model's name is a struct in kinegen::models,
// and each parameter a member of its Params. Such names stay valid in the file (analyze,
// eval and check accept them); only `generate` refuses them, with the reason.
#pragma once

#include <string>
#include <vector>

#include "kinegen/codegen/model/mechanism.hpp"

namespace kinegen::codegen {

// Where a user name appears in the generated header.
enum class HeaderName { kModel, kParameter };

// Why `name` would break the generated header where it appears, or "" when it would not.
std::string header_name_conflict(const std::string& name, HeaderName where);

// The identifiers the emitter declares in a model's struct (members, types and helpers), and
// those its code uses unqualified, which a struct of the same name would hide.
const std::vector<std::string>& header_member_names();

// Throws InputError (naming the item and its line) for the first name of `m` that
// header_name_conflict refuses.
void check_header_names(const Mechanism& m);

// Whether `ns` is a C++ nested-namespace name (a::b::c) whose parts are valid names and not
// reserved (std, kinegen, macros); `generate --namespace` takes one.
std::string namespace_conflict(const std::string& ns);

}  // namespace kinegen::codegen

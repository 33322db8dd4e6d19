// The model stage: a mechanism file read into plain, validated data.
//
// Takes: a mechanism file (YAML text, load_mechanism / parse_mechanism) and the CSV tables its
// `table:` drivers and `--input` options name. Gives: a Mechanism (bodies, parameters, points,
// Constraints whose kind is an entry of the registry, constraints/registry.hpp; expressions
// kept as text, Expr, with their SourceLoc) and the tables' Splines (table.hpp). Throws
// InputError naming the file, the item and the YAML line. Next: the symbolic stage.
#pragma once

#include "kinegen/codegen/model/mechanism.hpp"
#include "kinegen/codegen/model/table.hpp"

// The io stage: what reaches a file or a stream.
//
// Takes: text, and for drawings a CompiledModel with AnimateOptions (animate_svg runs the
// analysis it draws). Gives: files written atomically or not at all (OutputFile: generated
// headers, CSV, SVG, JSON on standard output; OutputError, exit 1) and SVG pictures
// (animate.hpp), and the page of `kinegen view` (view.hpp). Numbers are printed by base/format.hpp; the CSV rows themselves are
// csv_header/csv_row in analysis/analysis.hpp, the JSON of `kinegen eval` is in cli/eval.cpp.
#pragma once

#include "kinegen/codegen/io/animate.hpp"
#include "kinegen/codegen/io/output_file.hpp"
#include "kinegen/codegen/io/view.hpp"

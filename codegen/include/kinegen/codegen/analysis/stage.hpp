// The analysis stage: the mechanism solved in-process.
//
// Takes: a CompiledModel (compile stage: owns the model, symbolic, program and structure
// stages' results, built from a file or a Mechanism) and a TimeGrid with options. Gives:
// StateRows (run_analysis: t, q, qd, qdd, points, outputs, and on request sensitivities and
// forces: the symbolic stage's ForceModel and parameter derivatives evaluated, forces.hpp and
// sensitivity.hpp), by the same block program the generated Solver runs (BlockInterpreter) or
// by the dense or sparse Newton on all of Phi_q; ReferenceRows in CLN arithmetic
// (reference.hpp); CheckRows of the derivatives against independent truths (check.hpp);
// tolerance figures (tolerance.hpp). Throws AnalysisError (exit 1). The evaluator
// (evaluator.hpp) runs a Program on any scalar type in the order the emitted C++ computes it;
// model_evaluator.hpp runs a compiled model's programs (ModelEvaluator, ProgramSystem, evaluate).
// Next: io.
#pragma once

#include "kinegen/codegen/analysis/analysis.hpp"
#include "kinegen/codegen/analysis/block_interpreter.hpp"
#include "kinegen/codegen/analysis/check.hpp"
#include "kinegen/codegen/analysis/equilibrium.hpp"
#include "kinegen/codegen/analysis/evaluator.hpp"
#include "kinegen/codegen/analysis/forces.hpp"
#include "kinegen/codegen/analysis/kinematics.hpp"
#include "kinegen/codegen/analysis/linearize.hpp"
#include "kinegen/codegen/analysis/model_evaluator.hpp"
#include "kinegen/codegen/analysis/reference.hpp"
#include "kinegen/codegen/analysis/sensitivity.hpp"
#include "kinegen/codegen/analysis/tangent.hpp"
#include "kinegen/codegen/analysis/tolerance.hpp"

// The compile stage's programs beyond ModelPrograms (compile/programs.hpp), each lowered once
// on first use for both consumers.
#include "kinegen/codegen/compile/programs.hpp"

#include <stdexcept>

#include "kinegen/codegen/compile/compiled_model.hpp"
#include "kinegen/codegen/program/repeated.hpp"  // same_expressions
#include "kinegen/codegen/symbolic/sensitivity.hpp"
#include "kinegen/codegen/symbolic/stop_when.hpp"

namespace kinegen::codegen {

namespace {

// The tangent's pieces in one list, in TangentProgram's order, and where each starts.
std::vector<GiNaC::ex> tangent_expressions(const TangentModel& t,
                                           const std::vector<GiNaC::ex>& applied,
                                           std::vector<int>& begin) {
  const SparseExpr* parts[] = {&t.nu_q,    &t.gamma_q, &t.gamma_qd,  &t.phi_w,      &t.nu_w,
                               &t.gamma_w, nullptr,    &t.applied_q, &t.applied_qd, &t.applied_w};
  std::vector<GiNaC::ex> all = t.phi_qq.value;
  begin = {0};
  for (const SparseExpr* p : parts) {
    begin.push_back(static_cast<int>(all.size()));
    const auto& v = p ? p->value : applied;
    all.insert(all.end(), v.begin(), v.end());
  }
  begin.push_back(static_cast<int>(all.size()));
  return all;
}

}  // namespace

ForcePrograms compile_forces(const ForceModel& forces, const SymbolTable& symbols,
                             const SymbolicModel& model, bool fold) {
  const auto folded = [&](std::vector<GiNaC::ex> v) {
    if (fold)
      for (auto& e : v) e = substitute_params(e, symbols, model.param_values);
    return v;
  };
  return {lower(folded(forces.applied), symbols), lower(folded(forces.nonconservative), symbols),
          lower(folded({forces.potential}), symbols)};
}

const BlockProgram& CompiledModel::block_program() const {
  if (!structure().order.perfect)
    throw std::logic_error("CompiledModel::block_program: the structure has no block order");
  if (!block_program_)
    block_program_ =
        std::make_unique<BlockProgram>(build_block_program(symbolic_, *symbols_, structure()));
  return *block_program_;
}

const ForceModel& CompiledModel::forces() const {
  if (!forces_)
    forces_ = std::make_unique<ForceModel>(
        derive_forces(mechanism_, *symbols_, symbolic_, mechanism_.forces));
  return *forces_;
}

bool CompiledModel::same_forces(const ForceModel& f) const {
  const ForceModel& own = forces();
  return &f == &own || (same_expressions(f.applied, own.applied) &&
                        same_expressions(f.nonconservative, own.nonconservative) &&
                        f.potential.is_equal(own.potential));
}

std::shared_ptr<const ForcePrograms> CompiledModel::force_programs(const ForceModel& f) const {
  const auto build = [&] {
    return std::make_shared<const ForcePrograms>(
        compile_forces(f, *symbols_, symbolic_, options_.fold_params));
  };
  if (!same_forces(f)) return build();
  if (!force_programs_) force_programs_ = build();
  return force_programs_;
}

std::shared_ptr<const TangentProgram> CompiledModel::tangent_program(const ForceModel& f) const {
  const auto build = [&] {
    auto t = std::make_shared<TangentProgram>();
    t->tangent = derive_tangent(mechanism_, *symbols_, symbolic_, f);
    std::vector<GiNaC::ex> all = tangent_expressions(t->tangent, f.applied, t->begin);
    if (options_.fold_params)
      for (auto& e : all) e = substitute_params(e, *symbols_, symbolic_.param_values);
    t->program = lower(all, *symbols_);
    return std::shared_ptr<const TangentProgram>(std::move(t));
  };
  if (!same_forces(f)) return build();
  if (!tangent_program_) tangent_program_ = build();
  return tangent_program_;
}

const FreePrograms& CompiledModel::free_programs() const {
  if (!free_programs_) {
    const SymbolTable& sym = *symbols_;
    std::vector<GiNaC::ex> gradient, a0;
    for (std::size_t k = 0; k < symbolic_.free_values.size(); ++k) {
      GiNaC::ex acc = 0;
      for (int c = 0; c < nq(); ++c) {
        gradient.push_back(symbolic_.free_values[k].diff(sym.q(c)));
        acc += symbolic_.free_rates[k].diff(sym.q(c)) * sym.qd(c);
      }
      a0.push_back(acc);
    }
    free_programs_ = std::make_unique<FreePrograms>(
        FreePrograms{lower(symbolic_.free_values, sym), lower(symbolic_.free_rates, sym),
                     lower(gradient, sym), lower(a0, sym)});
  }
  return *free_programs_;
}

const StopPrograms& CompiledModel::stop_programs() const {
  if (!stop_programs_) {
    std::vector<GiNaC::ex> outputs{symbolic_.stop_when};
    const std::vector<GiNaC::ex> rate = stop_when_rate(symbolic_, *symbols_);
    outputs.insert(outputs.end(), rate.begin(), rate.end());
    stop_programs_ = std::make_unique<StopPrograms>(
        StopPrograms{lower(outputs, *symbols_), outputs.size(), !rate.empty()});
  }
  return *stop_programs_;
}

const ParameterPrograms& CompiledModel::parameter_programs(const std::vector<int>& params,
                                                           bool outputs) const {
  auto& slot = parameter_programs_[{params, outputs}];
  if (!slot) {
    slot = std::make_unique<ParameterPrograms>();
    slot->phi_p_expressions = derive_phi_p(symbolic_, *symbols_, params);
    slot->phi_p = lower(slot->phi_p_expressions, *symbols_);
    if (outputs) slot->output_p = lower(derive_output_p(symbolic_, *symbols_, params), *symbols_);
  }
  return *slot;
}

}  // namespace kinegen::codegen

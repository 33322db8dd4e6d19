// The block structure of Phi_q as the block_linear kernel reads it, at run time (private to
// the analysis stage). The kernel (kernels/block_linear.hpp) reads a model's structure tables
// as static members of a type S, which a generated header declares as constants; RuntimeBlocks
// is such a type whose members point at tables built from a CompiledModel's Structure, bound
// for the current thread by BlockTables::Binding. So the analysis solves Phi_q X = B and
// Phi_q^T Y = B through the blocks with the same kernel functions as generated code.
#pragma once

#include <vector>

#include "kinegen/codegen/compile/compiled_model.hpp"

namespace kinegen::codegen {

struct RuntimeBlocks {
  static constexpr int max_block_size = 16;  // as the emitter's limit for these solves
  inline static thread_local int nq = 0, num_blocks = 0;
  inline static thread_local const int* block_begin = nullptr;
  inline static thread_local const int* block_rows = nullptr;
  inline static thread_local const int* block_cols = nullptr;
  inline static thread_local const int* coordinate_block = nullptr;
  inline static thread_local const int* coordinate_slot = nullptr;
  inline static thread_local const int* jac_row_begin = nullptr;
  inline static thread_local const int* jac_cols = nullptr;
  inline static thread_local const double* coordinate_scales = nullptr;
};

class BlockTables {
 public:
  // Whether the structure serves: a perfect BLT order of a square Phi_q, blocks of at most
  // RuntimeBlocks::max_block_size, Phi_q's entries sorted by row.
  static bool supported(const CompiledModel& model) {
    const Structure& st = model.structure();
    const auto& rows = model.programs().jac_rows;
    for (std::size_t k = 1; k < rows.size(); ++k)
      if (rows[k] < rows[k - 1]) return false;
    return model.nq() == model.nc() && st.order.perfect && !st.plans.empty() &&
           st.largest_block() <= RuntimeBlocks::max_block_size;
  }

  explicit BlockTables(const CompiledModel& model)
      : nq_(model.nq()), scales_(model.symbolic().coordinate_scales) {
    const Structure& st = model.structure();
    block_.assign(nq_, 0);
    slot_.assign(nq_, 0);
    begin_.push_back(0);
    for (std::size_t k = 0; k < st.order.blocks.size(); ++k) {
      const Block& b = st.order.blocks[k];
      for (std::size_t i = 0; i < b.cols.size(); ++i) {
        block_[b.cols[i]] = static_cast<int>(k);
        slot_[b.cols[i]] = static_cast<int>(cols_.size());
        rows_.push_back(b.rows[i]);
        cols_.push_back(b.cols[i]);
      }
      begin_.push_back(static_cast<int>(cols_.size()));
    }
    const auto& jr = model.programs().jac_rows;
    std::size_t e = 0;
    for (int r = 0; r <= model.nc(); ++r) {
      while (e < jr.size() && jr[e] < r) ++e;
      row_begin_.push_back(static_cast<int>(e));
    }
    jac_cols_ = model.programs().jac_cols;
  }

  // Points RuntimeBlocks at these tables while it lives (and back at the previous ones).
  class Binding {
   public:
    explicit Binding(const BlockTables& t) : saved_(snapshot()) { set(t); }
    ~Binding() { restore(saved_); }
    Binding(const Binding&) = delete;
    Binding& operator=(const Binding&) = delete;

   private:
    struct Saved {
      int nq, num_blocks;
      const int *begin, *rows, *cols, *block, *slot, *row_begin, *jac_cols;
      const double* scales;
    };
    static Saved snapshot() {
      using R = RuntimeBlocks;
      return {R::nq,         R::num_blocks,       R::block_begin,     R::block_rows,
              R::block_cols, R::coordinate_block, R::coordinate_slot, R::jac_row_begin,
              R::jac_cols,   R::coordinate_scales};
    }
    static void restore(const Saved& s) {
      using R = RuntimeBlocks;
      R::nq = s.nq;
      R::num_blocks = s.num_blocks;
      R::block_begin = s.begin;
      R::block_rows = s.rows;
      R::block_cols = s.cols;
      R::coordinate_block = s.block;
      R::coordinate_slot = s.slot;
      R::jac_row_begin = s.row_begin;
      R::jac_cols = s.jac_cols;
      R::coordinate_scales = s.scales;
    }
    static void set(const BlockTables& t) {
      restore({t.nq_, static_cast<int>(t.begin_.size()) - 1, t.begin_.data(), t.rows_.data(),
               t.cols_.data(), t.block_.data(), t.slot_.data(), t.row_begin_.data(),
               t.jac_cols_.data(), t.scales_.data()});
    }
    Saved saved_;
  };

 private:
  int nq_;
  std::vector<double> scales_;
  std::vector<int> begin_, rows_, cols_, block_, slot_, row_begin_, jac_cols_;
};

}  // namespace kinegen::codegen

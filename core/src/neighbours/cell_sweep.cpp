#include "sphnl/neighbours/cell_sweep.hpp"

#include <algorithm>

namespace sphnl {

void CellSweep::prepare(const Gridder& gridder, ParticleSet& ps, unsigned mask, int threads, bool gather,
                        bool private_outputs) {
  if (static_cast<int>(scratch_.size()) < threads) scratch_.resize(threads);
  const std::size_t capacity = 14 * static_cast<std::size_t>(gridder.max_cell_count()) + kFilterSlack;
  const unsigned outputs = mask & (fields::force_out | fields::kgc_m_out);
  for (int t = 0; t < threads; ++t) {
    Scratch& s = scratch_[t];
    if (s.cell_index.size() < capacity) {
      s.cell_index.resize(capacity);
      s.survivors.resize(capacity);
    }
    if (gather) s.buffer.reserve(capacity);
    s.target = ParticleView::of(ps);
    if (t > 0 && outputs && private_outputs) s.private_acc.attach(s.target, ps.size(), outputs);
  }
}

void CellSweep::split_keys(const CellGrid& grid, const CellOrder& order, const Gridder& gridder,
                           const ParticleSet& ps, int threads) {
  const std::uint32_t num_keys = order.num_keys();
  if (threads == 1 || split_ == ThreadSplit::dynamic) {  // dynamic: no cut, the threads take chunks
    thread_begin_.assign({0, num_keys});
    return;
  }
  std::uint32_t* idx = scratch_[0].cell_index.data();
  weight_.resize(num_keys);
  if (split_ == ThreadSplit::interactions) {
    // Pair work: boundary-boundary pairs never reach the kernel, and a fluid
    // particle in the water meets more partners than one in a splash or
    // beside a wall. Counted as the sweep meets the pairs (half stencil), so
    // the pairs across the cut are charged to the thread that computes them.
    fluid_.resize(num_keys);
    boundary_.resize(num_keys);
    for (std::uint32_t key = 0; key < num_keys; ++key) {
      const std::uint32_t n = gridder.gather_cell(key, idx);
      std::uint32_t f = 0;
      for (std::uint32_t k = 0; k < n; ++k) f += ps.type[idx[k]] == ParticleType::fluid;
      fluid_[key] = f;
      boundary_[key] = n - f;
    }
    sweep_pair_work(grid, order, fluid_, boundary_, weight_);
  } else {
    // Work of a home cell ~ its fluid particles; boundary particles only meet
    // fluid ones, so they weigh a quarter.
    for (std::uint32_t key = 0; key < num_keys; ++key) {
      const std::uint32_t n = gridder.gather_cell(key, idx);
      double w = 0;
      for (std::uint32_t k = 0; k < n; ++k) w += ps.type[idx[k]] == ParticleType::fluid ? 1.0 : 0.25;
      weight_[key] = w;
    }
  }
  // Weights are counted once per sweep.
  cut_key_ranges(weight_, threads, thread_begin_);
}

void CellSweep::reduce(ParticleSet& ps, unsigned outputs, int threads) {
  for (int t = 1; t < threads; ++t) scratch_[t].private_acc.add_into(ps, outputs);
}

std::size_t CellSweep::bytes() const {
  // The thread split (thread_begin_, weight_) exists once, whatever the thread count.
  std::size_t b = thread_begin_.capacity() * sizeof(std::uint32_t) +
                  (weight_.capacity() + fluid_.capacity() + boundary_.capacity()) * sizeof(double) + phases_.bytes();
  for (const auto& s : scratch_)
    b += s.buffer.bytes() + (s.cell_index.capacity() + s.survivors.capacity() + s.fluid_slots.capacity() + s.block_pairs.capacity()) * sizeof(std::uint32_t) + s.lanes.capacity() +
         s.private_acc.bytes();
  return b;
}

}  // namespace sphnl

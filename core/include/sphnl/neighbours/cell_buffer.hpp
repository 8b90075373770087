#pragma once
// CellBuffer: the particles of one home cell and its 13 forward neighbour
// cells, copied into small contiguous arrays. The distance filter and the pair
// kernel then run on L1-resident data whatever the gridder and particle order;
// accumulated results are added back to the particles once per home cell.
// For precision=mixed it also holds a float copy (fill_float): positions
// relative to the first entry, so that float keeps the differences of nearby
// particles to a few 1e-9 m wherever the tank is, and float accumulators, whose
// per-home-cell partial sums are added to the particles' double totals.
#include <cstdint>
#include <vector>

#include "sphnl/particle_view.hpp"
#include "sphnl/particles.hpp"

namespace sphnl {

class CellBuffer {
 public:
  void reserve(std::size_t capacity);
  std::size_t capacity() const { return index_.size(); }
  /// Copies the fields named by `mask` of particles index[0..count) of `ps`.
  void gather(const ParticleSet& ps, const std::uint32_t* index, std::uint32_t count, unsigned mask);
  /// Fills the float copy of the fields named by `mask` from the gathered
  /// double ones (after any shift_y) and zeroes its float accumulators.
  void fill_float(unsigned mask);
  /// Adds the accumulators named by `mask` into the accumulator arrays of
  /// `target` (the particles' own, or a thread's private copy); with
  /// fields::float_copy in `mask`, force_out comes from the float copy.
  void scatter_add(const ParticleView& target, unsigned mask) const;
  /// Adds `shift` to the gathered y of entries [begin, end): the periodic image
  /// of a cell across the seam (the particles' own y is untouched).
  void shift_y(std::uint32_t begin, std::uint32_t end, double shift);
  ParticleView view() { return view_; }
  ParticleViewF float_view() { return float_view_; }
  std::uint32_t size() const { return size_; }
  std::uint32_t* index() { return index_.data(); }
  std::size_t bytes() const;

 private:
  std::uint32_t size_ = 0;
  std::vector<std::uint32_t> index_;
  // one array per field; indices into `arrays_` are fixed by the .cpp
  std::vector<std::vector<double>> arrays_;
  std::vector<std::vector<float>> float_arrays_;  // same slots; allocated by the first fill_float
  ParticleView view_;
  ParticleViewF float_view_;
};

}  // namespace sphnl

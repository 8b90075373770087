#pragma once
// HomeCandidates: the distance filter of the home particles of one gathered
// home cell (CellBuffer of the cell sweep): home particle i is tested against
// every later entry of the buffer (the rest of its cell and the 13 forward
// cells), so each pair is seen once. With `SkipBoundaryPairs` (the ablation
// `skip_boundary_pairs=true`, README.md) a boundary home particle is tested
// against the fluid entries only, so boundary-boundary candidates are never
// distance-tested, as a Verlet list's loop never meets them (it stores none).
// Either way no boundary-boundary pair survives (docs/PHYSICS.md), and the
// survivors come out in the same buffer order, so the pair kernel sums the
// same terms in the same order. `first_partner` > 0 (a ghost home cell of a
// distributed run, CellSweep::Scratch::first_partner) tests the home
// particles against the entries from there on only: not against each other.
#include <cstdint>
#include <vector>

#include "sphnl/neighbours/pair_filter.hpp"
#include "sphnl/particle_view.hpp"

namespace sphnl {

template <bool Simd, bool SkipBoundaryPairs>
class HomeCandidates {
 public:
  /// `v` views the buffer's `total` entries; `fluid_slots` is scratch.
  HomeCandidates(const ParticleView& v, std::uint32_t total, std::vector<std::uint32_t>& fluid_slots,
                 std::uint32_t first_partner = 0)
      : v_(v), total_(total), first_partner_(first_partner) {
    if constexpr (SkipBoundaryPairs) {
      if (fluid_slots.size() < total + kFilterSlack) fluid_slots.resize(total + kFilterSlack);
      fluid_ = fluid_slots.data();
      for (std::uint32_t k = 0; k < total; ++k) {
        fluid_[n_fluid_] = k;  // branch-free compaction
        n_fluid_ += v.is_fluid[k] > 0.0;
      }
    }
  }

  /// Writes the survivors of home entry i (r^2 in (min_r2, radius2)) to `out`
  /// and returns how many; adds the candidates tested to `tested`. Call with
  /// increasing i.
  int filter(std::uint32_t i, double radius2, std::uint32_t* out, std::uint64_t& tested,
             double min_r2 = CubicSpline::kMinR2) {
    const std::uint32_t first = i + 1 > first_partner_ ? i + 1 : first_partner_;
    if constexpr (SkipBoundaryPairs) {
      if (!(v_.is_fluid[i] > 0.0)) {
        while (next_ < n_fluid_ && fluid_[next_] < first) ++next_;
        tested += n_fluid_ - next_;
        return filter_list<Simd>(v_, i, fluid_ + next_, static_cast<int>(n_fluid_ - next_), radius2, out, min_r2);
      }
    }
    tested += total_ - first;
    return filter_range<Simd>(v_, i, first, total_, radius2, out, min_r2);
  }

 private:
  ParticleView v_;
  std::uint32_t total_;
  std::uint32_t first_partner_;
  std::uint32_t* fluid_ = nullptr;  // buffer slots of fluid entries, increasing
  std::uint32_t n_fluid_ = 0, next_ = 0;
};

}  // namespace sphnl

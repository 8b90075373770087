// The parts of the gridder interface (paper §2.3) that are not inline, and the
// run-time factory.
#include "sphnl/gridders/gridder.hpp"

#include <cmath>

#include "sphnl/gridders/linked_list.hpp"
#include "sphnl/gridders/preconditioned_vector.hpp"
#include "sphnl/gridders/sliding_vector.hpp"
#include "sphnl/gridders/sliding_vector_shift_all.hpp"
#include "sphnl/gridders/static_matrix.hpp"
#include "sphnl/input_error.hpp"

namespace sphnl {

void Gridder::cell_order_permutation(std::vector<std::uint32_t>& order) const {
  // Gathers straight into `order` (no temporary): its capacity, kept between
  // builds, is the only memory this needs.
  order.resize(0);
  for (std::uint32_t k = 0; k < num_keys_; ++k) {
    const std::size_t at = order.size();
    order.resize(at + max_cell_count_);
    order.resize(at + gather_cell(k, order.data() + at));
  }
}

int default_max_parts_in_cell(const GridderOptions& o) {
  if (!(o.dx > 0) || !(o.h > 0)) return 0;
  const double side = 2.2 * o.h;  // 2h plus a Verlet skin allowance
  const double planes = std::floor(side / o.dx + 1e-6) + 1;  // lattice planes a cell of that side can cut
  return static_cast<int>(std::ceil(1.3 * o.particles_per_dx3 * planes * planes * planes));
}
std::unique_ptr<Gridder> make_gridder(GridderKind kind, const GridderOptions& options) {
  switch (kind) {
    case GridderKind::A:
      if (options.sliding_variant == SlidingVariant::shift_all) return std::make_unique<SlidingVectorShiftAll>();
      return std::make_unique<SlidingVector>();
    case GridderKind::B: return std::make_unique<PreconditionedVector>();
    case GridderKind::C: return std::make_unique<StaticMatrix>(options);
    case GridderKind::D: return std::make_unique<LinkedList>();
  }
  throw ConfigError("gridder: unknown value; allowed: A, B, C, D");
}

}  // namespace sphnl

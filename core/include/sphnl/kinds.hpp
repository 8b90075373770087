#pragma once
// The run-time choices of the neighbour search, as small enums: which gridder
// (paper §2.3), which cell order (§2.4) and which pair source (§2.5). Kept
// apart from config.hpp so that the algorithms do not depend on the config
// or JSON; their names (to_string) are the config's values.
#include <cstdint>

namespace sphnl {

enum class GridderKind : std::uint8_t { A, B, C, D };                            // paper §2.3
enum class CellOrderKind : std::uint8_t { sort_x, sort_xy, sort_xyz, hilbert };  // §2.4
enum class ListKind : std::uint8_t { cll, vlc, vlx };                            // §2.5

// Ablations (README.md, "Ablations"): run-time switches that test one
// explanation each of why sphnl's results differ from the paper's.
/// How the cell-linked list reads a home cell and its 13 forward cells:
/// `gather` copies them into a contiguous CellBuffer first; `direct` reads the
/// particle arrays in place through the gridder's own structure, as the
/// paper's code did; `masked` reads the gathered copies in blocks of 8
/// consecutive entries with a lane mask (no compaction, no gather).
enum class PairLoopKind : std::uint8_t { gather, direct, masked };
/// Gridder A (§2.3, sliding dynamic vector): after an insertion, `occupied`
/// re-adjusts CellsBegin only up to the last cell holding a particle so far
/// (an insertion in cell order appends at O(1)); `shift_all` re-adjusts it for
/// every later cell of the grid (O(cells) per insertion whatever the order).
enum class SlidingVariant : std::uint8_t { occupied, shift_all };
/// Memory order of the particles at t = 0 (and after a restore): as the case
/// generator made them (nearly cell-ordered), or shuffled with a fixed seed.
enum class InitialOrder : std::uint8_t { generated, shuffled };
/// The order of each cell's particles when the arrays are reordered (config
/// `inner_order`): `index`, increasing particle index (a stable sort by cell,
/// as the paper's reordering, §2.4); `morton`, the Z-order of the particle's
/// sub-cell in a 4 x 4 x 4 division of its cell, so that a run of 8
/// consecutive particles (a j-block of `pair_loop=masked`) is a compact
/// cluster rather than a slab of the cell.
enum class InnerOrder : std::uint8_t { index, morton };

/// How threads > 1 keep from adding to one particle at once in a pair pass
/// (both particles of a pair are updated): `private_accumulators` (config
/// value `private`): every thread but the first adds into its own zeroed copy
/// of the accumulators, summed afterwards; `phased`: no copies, the home cells
/// run in phases in which no two threads write one cell (ThreadPhases).
enum class ThreadUpdates : std::uint8_t { private_accumulators, phased };

/// How a cell sweep cuts its home cells into one contiguous key range per
/// thread (config `thread_split`): `fluid`, equal fluid weight (a fluid
/// particle 1, a boundary one 1/4); or `interactions`, equal estimated pair
/// work (sweep_pair_work in neighbours/cell_work.hpp: the candidate pairs
/// with a fluid particle that each home cell meets in itself and its 13
/// forward cells); or `dynamic`, no cut: the threads take chunks of
/// consecutive home cells as they finish the last (OpenMP dynamic schedule),
/// which balances whatever a cell costs, but makes which thread sums which
/// pair, and so the last bits of the results, vary between runs. Only with
/// `thread_updates=private` (phased updates need fixed key ranges).
enum class ThreadSplit : std::uint8_t { fluid, interactions, dynamic };

/// Arithmetic of the pair kernel (config `precision`): `double` throughout
/// (config value `double`), or `mixed`: differences of positions and
/// velocities in double rounded to float, the pair's kernel and terms in
/// float, every sum over pairs and the time integration in double
/// (pair_kernel.hpp). The neighbour search is double in both.
enum class Precision : std::uint8_t { double_precision, mixed };

/// What a distributed run (mpirun -np P) balances when it cuts the ranks' key
/// ranges (config `balance_by`): `interactions`, the candidate pairs each
/// cell's particles meet in the cells around it (interaction_weights in
/// parallel/decomposition.hpp), or `particles`, a fluid particle 1 and a
/// boundary one 1/4 (DomainExchange::weight).
enum class BalanceBy : std::uint8_t { interactions, particles };

const char* to_string(GridderKind g);
const char* to_string(CellOrderKind o);
const char* to_string(ListKind l);
const char* to_string(PairLoopKind p);
const char* to_string(SlidingVariant v);
const char* to_string(InitialOrder o);
const char* to_string(InnerOrder o);
const char* to_string(ThreadUpdates u);
const char* to_string(ThreadSplit s);
const char* to_string(Precision p);
const char* to_string(BalanceBy b);

}  // namespace sphnl

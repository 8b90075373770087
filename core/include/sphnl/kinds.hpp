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

const char* to_string(GridderKind g);
const char* to_string(CellOrderKind o);
const char* to_string(ListKind l);

}  // namespace sphnl

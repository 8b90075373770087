#include "sphnl/kinds.hpp"

namespace sphnl {

// The names are the config's values (config.cpp parses the same spellings).
const char* to_string(GridderKind g) {
  constexpr const char* names[] = {"A", "B", "C", "D"};
  return names[static_cast<int>(g)];
}
const char* to_string(CellOrderKind o) {
  constexpr const char* names[] = {"sort_x", "sort_xy", "sort_xyz", "hilbert"};
  return names[static_cast<int>(o)];
}
const char* to_string(ListKind l) {
  constexpr const char* names[] = {"cll", "vlc", "vlx"};
  return names[static_cast<int>(l)];
}

}  // namespace sphnl

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

const char* to_string(PairLoopKind p) {
  constexpr const char* names[] = {"gather", "direct", "masked"};
  return names[static_cast<int>(p)];
}
const char* to_string(SlidingVariant v) {
  constexpr const char* names[] = {"occupied", "shift_all"};
  return names[static_cast<int>(v)];
}
const char* to_string(InitialOrder o) {
  constexpr const char* names[] = {"generated", "shuffled"};
  return names[static_cast<int>(o)];
}
const char* to_string(InnerOrder o) {
  constexpr const char* names[] = {"index", "morton"};
  return names[static_cast<int>(o)];
}
const char* to_string(ThreadUpdates u) {
  constexpr const char* names[] = {"private", "phased"};
  return names[static_cast<int>(u)];
}
const char* to_string(ThreadSplit s) {
  constexpr const char* names[] = {"fluid", "interactions", "dynamic"};
  return names[static_cast<int>(s)];
}
const char* to_string(Precision p) {
  constexpr const char* names[] = {"double", "mixed"};
  return names[static_cast<int>(p)];
}
const char* to_string(BalanceBy b) {
  constexpr const char* names[] = {"interactions", "particles"};
  return names[static_cast<int>(b)];
}

}  // namespace sphnl

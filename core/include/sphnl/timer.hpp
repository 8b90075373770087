#pragma once
#include <chrono>

namespace sphnl {

/// Wall-clock seconds since construction or the last lap().
class Stopwatch {
 public:
  Stopwatch() : last_(clock::now()) {}
  double lap() {
    const auto now = clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }

 private:
  using clock = std::chrono::steady_clock;
  clock::time_point last_;
};

}  // namespace sphnl

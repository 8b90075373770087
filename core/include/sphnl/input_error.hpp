#pragma once
// ConfigError: the one exception type for invalid user input (config keys,
// gridder and order choices); the message names the key or path and what is
// allowed.
#include <stdexcept>

namespace sphnl {

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace sphnl

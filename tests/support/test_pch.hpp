#pragma once
// The precompiled header of the test executables (CMakeLists.txt,
// SPHNL_TEST_PCH): GoogleTest, the standard headers and the library headers
// most test files include. Each test file still includes what it uses; this
// only saves parsing the same headers once per file.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "sphnl/case.hpp"
#include "sphnl/config.hpp"
#include "sphnl/neighbours/cell_linked_list.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/particles.hpp"
#include "sphnl/simulation.hpp"

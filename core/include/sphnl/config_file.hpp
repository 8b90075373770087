#pragma once
// Reading a run-config file (`sphnl run --config FILE`): strict JSON (a
// duplicate key is an error, comments allowed) and every key checked against
// the config table, each error prefixed with FILE:LINE:COL of its key.
#include <string>

#include <nlohmann/json_fwd.hpp>

namespace sphnl {

/// The JSON object of `path`, every key and value already validated by
/// config_from_json. Throws ConfigError naming the file, line and column.
nlohmann::json read_config_file(const std::string& path);

/// The same for text already in memory (`name` is used in messages).
nlohmann::json parse_config_text(const std::string& text, const std::string& name);

}  // namespace sphnl

#include "sphnl/config_file.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "sphnl/config.hpp"
#include "sphnl/json_reader.hpp"

namespace sphnl {

using nlohmann::json;

json parse_config_text(const std::string& text, const std::string& name) {
  ParsedJson doc;
  try {
    doc = parse_json_strict(text, name, /*allow_comments=*/true);
  } catch (const JsonFileError& e) {
    const std::string what = e.what();
    if (what.find("not valid JSON") == std::string::npos) throw ConfigError(what);
    throw ConfigError(what + "; expected an object such as {\"particles\": 31239, \"gridder\": \"B\"}");
  }
  if (!doc.value.is_object())
    throw ConfigError(name + ": a config file must hold a JSON object of key: value pairs, such as {\"particles\": 31239}");
  // Each key alone, so the error points at the line to edit.
  for (const auto& [key, value] : doc.value.items()) {
    try {
      config_from_json(json{{key, value}});
    } catch (const ConfigError& e) {
      throw ConfigError(doc.where("/" + json_pointer_token(key)) + ": " + e.what());
    }
  }
  try {
    config_from_json(doc.value);  // the checks between keys (particles and dx, ...)
  } catch (const ConfigError& e) {
    throw ConfigError(name + ": " + e.what());
  }
  return std::move(doc.value);
}

json read_config_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError("cannot read config file '" + path + "': " + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_config_text(ss.str(), path);
}

}  // namespace sphnl

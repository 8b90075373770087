#pragma once
// A strict JSON reader for the harness's own input files (run configs,
// experiment definitions): a duplicate key is an error instead of silently
// keeping the last value, and every error and every key carries its line and
// column so a message can point at the place to edit.
#include <cstddef>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace sphnl {

/// 1-based line and column of a place in a text.
struct TextPos {
  std::size_t line = 0, column = 0;
};

/// Thrown for malformed or duplicate-key JSON; what() starts with "FILE:LINE:COL: ".
struct JsonFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct ParsedJson {
  nlohmann::json value;
  /// Position of every object key, by JSON pointer ("/sweep/tiny/gridder").
  std::map<std::string, TextPos> key_pos;
  std::string name;  // the file name used in messages

  /// "FILE:LINE:COL" of the key at `pointer`, or just "FILE" when unknown.
  std::string where(const std::string& pointer) const;
};

/// Parses `text` (named `name` in messages). `allow_comments`: // and /* */
/// comments are skipped (config files allow them, experiment files do not).
ParsedJson parse_json_strict(std::string_view text, const std::string& name, bool allow_comments = false);
/// Reads and parses a file; a file that cannot be read is a JsonFileError too.
ParsedJson read_json_strict(const std::string& path, bool allow_comments = false);

/// `key` escaped as one JSON-pointer token (RFC 6901: ~ -> ~0, / -> ~1).
std::string json_pointer_token(const std::string& key);

/// Line and column of byte `offset` of `text`.
TextPos text_position(std::string_view text, std::size_t offset);

}  // namespace sphnl

#include "sphnl/json_reader.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <vector>

namespace sphnl {

using nlohmann::json;

TextPos text_position(std::string_view text, std::size_t offset) {
  TextPos p{1, 1};
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++p.line;
      p.column = 1;
    } else {
      ++p.column;
    }
  }
  return p;
}

std::string json_pointer_token(const std::string& key) {
  std::string t;
  for (const char ch : key) {
    if (ch == '~') t += "~0";
    else if (ch == '/') t += "~1";
    else t += ch;
  }
  return t;
}

std::string ParsedJson::where(const std::string& pointer) const {
  const auto it = key_pos.find(pointer);
  if (it == key_pos.end()) return name;
  return name + ":" + std::to_string(it->second.line) + ":" + std::to_string(it->second.column);
}

namespace {

/// Iterator over the text that remembers the last character the lexer read:
/// nlohmann's SAX interface reports no position for keys, but the lexer has
/// just read a key's closing quote when it calls key().
class TrackingIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  TrackingIterator(const char* p, const char** last) : p_(p), last_(last) {}
  reference operator*() const {
    *last_ = p_;
    return *p_;
  }
  TrackingIterator& operator++() {
    ++p_;
    return *this;
  }
  TrackingIterator operator++(int) {
    TrackingIterator t = *this;
    ++p_;
    return t;
  }
  bool operator==(const TrackingIterator& o) const { return p_ == o.p_; }
  bool operator!=(const TrackingIterator& o) const { return p_ != o.p_; }

 private:
  const char* p_;
  const char** last_;
};

/// Builds the json value (as nlohmann's own DOM parser would), recording key
/// positions and refusing duplicate keys.
class StrictBuilder : public nlohmann::json_sax<json> {
 public:
  StrictBuilder(std::string_view text, const std::string& name, const char** last)
      : text_(text), name_(name), last_(last) {}

  bool null() override { return put(json(nullptr)); }
  bool boolean(bool v) override { return put(json(v)); }
  bool number_integer(number_integer_t v) override { return put(json(v)); }
  bool number_unsigned(number_unsigned_t v) override { return put(json(v)); }
  bool number_float(number_float_t v, const string_t&) override { return put(json(v)); }
  bool string(string_t& v) override { return put(json(v)); }
  bool binary(binary_t& v) override { return put(json::binary(v)); }
  bool start_object(std::size_t) override { return open(json::object()); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(json::array()); }
  bool end_array() override { return close(); }

  bool key(string_t& k) override {
    Frame& f = stack_.back();
    // The lexer has read the closing quote; the key starts at its opening one.
    const std::size_t close_quote = static_cast<std::size_t>(*last_ - text_.data());
    std::size_t open_quote = close_quote;
    while (open_quote > 0) {
      --open_quote;
      if (text_[open_quote] == '"' && (open_quote == 0 || text_[open_quote - 1] != '\\')) break;
    }
    const TextPos pos = text_position(text_, open_quote);
    const std::string ptr = f.pointer + "/" + json_pointer_token(k);
    if (!f.keys.insert(k).second) {
      error_ = name_ + ":" + std::to_string(pos.line) + ":" + std::to_string(pos.column) + ": duplicate key '" + k +
               "' (first at line " + std::to_string(out_.key_pos[ptr].line) +
               "); JSON keeps only one of them, so delete the one you do not mean";
      return false;
    }
    out_.key_pos[ptr] = pos;
    key_ = k;
    key_pointer_ = ptr;
    return true;
  }

  bool parse_error(std::size_t position, const std::string&, const nlohmann::detail::exception& ex) override {
    // position counts characters read, so the offending one is position - 1.
    const TextPos pos = text_position(text_, position > 0 ? position - 1 : 0);
    std::string what = ex.what();
    // nlohmann's message repeats a position of its own; keep the reason only.
    if (const auto colon = what.find(": syntax error"); colon != std::string::npos) what = what.substr(colon + 2);
    else if (const auto c2 = what.find("] "); c2 != std::string::npos) what = what.substr(c2 + 2);
    error_ = name_ + ":" + std::to_string(pos.line) + ":" + std::to_string(pos.column) + ": not valid JSON: " + what;
    return false;
  }

  ParsedJson& result() { return out_; }
  const std::string& error() const { return error_; }

 private:
  struct Frame {
    json* value;
    std::string pointer;
    std::set<std::string> keys;
  };

  /// Where the next value goes: the root, the next array element or the
  /// value of the key just read. Returns its JSON pointer in `ptr`.
  json* slot(std::string& ptr) {
    if (stack_.empty()) {
      ptr.clear();
      return &out_.value;
    }
    Frame& f = stack_.back();
    if (f.value->is_array()) {
      ptr = f.pointer + "/" + std::to_string(f.value->size());
      f.value->push_back(json());
      return &f.value->back();
    }
    ptr = key_pointer_;
    return &(*f.value)[key_];
  }
  bool put(json v) {
    std::string ptr;
    *slot(ptr) = std::move(v);
    return true;
  }
  bool open(json v) {
    std::string ptr;
    json* s = slot(ptr);
    *s = std::move(v);
    stack_.push_back(Frame{s, ptr, {}});
    return true;
  }
  bool close() {
    stack_.pop_back();
    return true;
  }

  std::string_view text_;
  std::string name_;
  const char** last_;
  ParsedJson out_;
  std::vector<Frame> stack_;
  std::string key_, key_pointer_, error_;
};

}  // namespace

ParsedJson parse_json_strict(std::string_view text, const std::string& name, bool allow_comments) {
  const char* last = text.data();
  StrictBuilder b(text, name, &last);
  const bool ok = json::sax_parse(TrackingIterator(text.data(), &last), TrackingIterator(text.data() + text.size(), &last),
                                  &b, json::input_format_t::json, /*strict=*/true, allow_comments);
  if (!ok) throw JsonFileError(b.error().empty() ? name + ": not valid JSON" : b.error());
  b.result().name = name;
  return std::move(b.result());
}

ParsedJson read_json_strict(const std::string& path, bool allow_comments) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw JsonFileError(path + ": cannot open (" + std::strerror(errno) + ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_json_strict(ss.str(), path, allow_comments);
}

}  // namespace sphnl

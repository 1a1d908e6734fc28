// Lexer for the pbrt-v4 scene format.
//
// The whole file is read into memory once and tokens are views into it, so
// the hot loop allocates nothing; only strings with escapes are copied when
// their value is asked for.  Scene files can be 100 MB of numbers.
#pragma once

#include "scene/scene.h"

#include <fmt/core.h>

#include <memory>
#include <string>
#include <string_view>

namespace theia {

struct Token {
  enum Kind { End, String, Bare, LBracket, RBracket };
  Kind kind = End;
  std::string_view text;  // strings: without the quotes, escapes not yet resolved
  bool escaped = false;   // a string containing backslash escapes
  int line = 0, column = 0;
};

// "FILE:LINE:COLUMN: error: MESSAGE" as a theia::Error.
[[noreturn]] void throw_at(const SourceLoc& loc, const std::string& message);
template <typename... Args>
[[noreturn]] void throw_at(const SourceLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
  throw_at(loc, fmt::format(f, std::forward<Args>(args)...));
}
// "FILE:LINE:COLUMN: MESSAGE" as a counted warning.
void warn_at(const SourceLoc& loc, const std::string& message);
template <typename... Args>
void warn_at(const SourceLoc& loc, fmt::format_string<Args...> f, Args&&... args) {
  warn_at(loc, fmt::format(f, std::forward<Args>(args)...));
}
std::string format_loc(const SourceLoc& loc);

class Tokenizer {
 public:
  Tokenizer(std::string text, std::string filename);
  // Reads the whole file; a missing file is reported at `included_from`
  // (or without a location for the top-level file).
  static std::unique_ptr<Tokenizer> from_file(const std::string& path, const SourceLoc* included_from);

  Token next();
  const Token& peek();
  const std::string& filename() const { return filename_; }
  SourceLoc loc(const Token& t) const { return {filename_, t.line, t.column}; }
  // The value of a String token with escapes resolved.
  std::string string_value(const Token& t) const;
  // A description of a token for messages: "\"abc\"", "[", "end of file".
  static std::string describe(const Token& t);

 private:
  Token scan();

  std::string text_;
  std::string filename_;
  const char* pos_ = nullptr;
  const char* end_ = nullptr;
  const char* line_start_ = nullptr;
  int line_ = 1;
  Token peeked_;
  bool has_peeked_ = false;
};

// Parses a whole bare token as a number ("-.5", "1e-3", "+3"); false if it is not one.
bool parse_number(std::string_view s, double* out);

}  // namespace theia

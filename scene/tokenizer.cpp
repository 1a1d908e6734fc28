#include "scene/tokenizer.h"

#include "core/log.h"

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace theia {

std::string format_loc(const SourceLoc& loc) { return fmt::format("{}:{}:{}", loc.file, loc.line, loc.column); }

void throw_at(const SourceLoc& loc, const std::string& message) {
  throw Error(fmt::format("{}: error: {}", format_loc(loc), message));
}

void warn_at(const SourceLoc& loc, const std::string& message) {
  log_warning_str(fmt::format("{}: {}", format_loc(loc), message));
}

Tokenizer::Tokenizer(std::string text, std::string filename) : text_(std::move(text)), filename_(std::move(filename)) {
  pos_ = text_.data();
  end_ = pos_ + text_.size();
  line_start_ = pos_;
}

std::unique_ptr<Tokenizer> Tokenizer::from_file(const std::string& path, const SourceLoc* included_from) {
  // Only regular files are opened: a FIFO would block open() for ever, a
  // device would read without end.
  std::error_code ec;
  auto status = std::filesystem::status(path, ec);
  bool irregular = !ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status);
  std::FILE* f = irregular ? nullptr : std::fopen(path.c_str(), "rb");
  if (!f) {
    std::string why = std::filesystem::is_directory(status) ? "it is a directory"
                      : irregular                           ? "it is not a regular file"
                                                            : std::strerror(errno);
    if (included_from) throw_at(*included_from, "cannot open \"{}\": {}, expected a readable file", path, why);
    throw Error(fmt::format("{}: error: cannot open the scene file: {}", path, why));
  }
  std::string text;
  std::fseek(f, 0, SEEK_END);
  long size = std::ftell(f);
  std::fseek(f, 0, SEEK_SET);
  if (size > 0) {
    text.resize(size_t(size));
    size_t got = std::fread(text.data(), 1, text.size(), f);
    text.resize(got);
  }
  std::fclose(f);
  return std::make_unique<Tokenizer>(std::move(text), path);
}

const Token& Tokenizer::peek() {
  if (!has_peeked_) {
    peeked_ = scan();
    has_peeked_ = true;
  }
  return peeked_;
}

Token Tokenizer::next() {
  if (has_peeked_) {
    has_peeked_ = false;
    return peeked_;
  }
  return scan();
}

Token Tokenizer::scan() {
  // Skip whitespace and comments, counting lines.
  while (pos_ < end_) {
    char c = *pos_;
    if (c == '\n') {
      ++line_;
      line_start_ = ++pos_;
    } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      ++pos_;
    } else if (c == '#') {
      const void* nl = std::memchr(pos_, '\n', size_t(end_ - pos_));
      pos_ = nl ? static_cast<const char*>(nl) : end_;
    } else {
      break;
    }
  }
  Token t;
  t.line = line_;
  t.column = int(pos_ - line_start_) + 1;
  if (pos_ >= end_) return t;

  char c = *pos_;
  if (c == '[' || c == ']') {
    t.kind = c == '[' ? Token::LBracket : Token::RBracket;
    t.text = std::string_view(pos_, 1);
    ++pos_;
    return t;
  }
  if (c == '"') {
    const char* start = ++pos_;
    while (true) {
      if (pos_ >= end_ || *pos_ == '\n')
        throw_at(loc(t), "unterminated string, expected a closing '\"' on the same line");
      if (*pos_ == '"') break;
      if (*pos_ == '\\') {
        t.escaped = true;
        if (++pos_ >= end_ || *pos_ == '\n')
          throw_at(loc(t), "unterminated string, expected a closing '\"' on the same line");
      }
      ++pos_;
    }
    t.kind = Token::String;
    t.text = std::string_view(start, size_t(pos_ - start));
    ++pos_;
    return t;
  }
  const char* start = pos_;
  while (pos_ < end_) {
    char d = *pos_;
    if (d == ' ' || d == '\n' || d == '\t' || d == '\r' || d == '"' || d == '[' || d == ']' || d == '#') break;
    ++pos_;
  }
  t.kind = Token::Bare;
  t.text = std::string_view(start, size_t(pos_ - start));
  return t;
}

std::string Tokenizer::string_value(const Token& t) const {
  if (!t.escaped) return std::string(t.text);
  std::string s;
  s.reserve(t.text.size());
  for (size_t i = 0; i < t.text.size(); ++i) {
    char c = t.text[i];
    if (c != '\\' || i + 1 == t.text.size()) {
      s += c;
      continue;
    }
    switch (char e = t.text[++i]) {
      case 'b': s += '\b'; break;
      case 'f': s += '\f'; break;
      case 'n': s += '\n'; break;
      case 'r': s += '\r'; break;
      case 't': s += '\t'; break;
      default: s += e; break;  // \\ \" \' and anything else stand for themselves
    }
  }
  return s;
}

std::string Tokenizer::describe(const Token& t) {
  switch (t.kind) {
    case Token::End: return "end of file";
    case Token::String: return fmt::format("\"{}\"", t.text);
    default: return std::string(t.text);
  }
}

bool parse_number(std::string_view s, double* out) {
  const char* b = s.data();
  const char* e = b + s.size();
  if (b != e && *b == '+') ++b;
  if (b == e || *b == '+') return false;
  auto [ptr, ec] = std::from_chars(b, e, *out);
  return ec == std::errc() && ptr == e;
}

}  // namespace theia

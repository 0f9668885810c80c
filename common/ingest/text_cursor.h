#pragma once
// Line-aware scanner over an in-memory text file: numbers via std::from_chars (no
// iostreams, no locale), line numbers kept for error messages.

#include <charconv>
#include <cstddef>
#include <cstdlib>
#include <string>
#include <string_view>

#include "dentmark/common/ingest/mesh.h"

namespace dentmark::ingest::detail {

class TextCursor {
 public:
  // A file's text (first_line 1) may open with a UTF-8 byte order mark, as Windows
  // tools write it: it is skipped.
  TextCursor(std::string path, std::string_view text, std::size_t first_line = 1)
      : path_(std::move(path)), p_(text.data()), end_(text.data() + text.size()), line_(first_line) {
    if (first_line == 1 && text.starts_with("\xEF\xBB\xBF")) p_ += 3;
  }

  bool at_end() const { return p_ >= end_; }
  std::size_t line() const { return line_; }
  const char* pos() const { return p_; }

  // Skips spaces and tabs (and '\r'), not newlines.
  void skip_blanks() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == ',')) ++p_;
  }
  // Skips blank lines and whitespace including newlines.
  void skip_space() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == '\n')) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
  }
  bool at_eol() {
    skip_blanks();
    return p_ >= end_ || *p_ == '\n';
  }
  // Moves past the next newline.
  void next_line() {
    while (p_ < end_ && *p_ != '\n') ++p_;
    if (p_ < end_) {
      ++p_;
      ++line_;
    }
  }
  std::string_view word() {
    skip_blanks();
    const char* b = p_;
    while (p_ < end_ && *p_ != ' ' && *p_ != '\t' && *p_ != '\r' && *p_ != '\n') ++p_;
    return {b, static_cast<std::size_t>(p_ - b)};
  }
  double number(const char* what) {
    skip_blanks();
    double v = 0.0;
    const char* b = p_;
    if (p_ < end_ && *p_ == '+') ++p_;
    auto r = std::from_chars(p_, end_, v);
    if (r.ec == std::errc::result_out_of_range) {
      // Denormals and huge values: still a number; keep what strtod would give.
      v = std::strtod(std::string(p_, static_cast<std::size_t>(r.ptr - p_)).c_str(), nullptr);
    } else if (r.ec != std::errc()) {
      p_ = b;
      fail(std::string("expected a number for ") + what);
    }
    p_ = r.ptr;
    return v;
  }
  long long integer(const char* what) {
    skip_blanks();
    long long v = 0;
    if (p_ < end_ && *p_ == '+') ++p_;
    auto r = std::from_chars(p_, end_, v);
    if (r.ec != std::errc()) fail(std::string("expected an integer for ") + what);
    p_ = r.ptr;
    return v;
  }
  [[noreturn]] void fail(const std::string& problem) const {
    throw IngestError(path_ + ": line " + std::to_string(line_) + ": " + problem);
  }

 private:
  std::string path_;
  const char* p_;
  const char* end_;
  std::size_t line_;
};

}  // namespace dentmark::ingest::detail

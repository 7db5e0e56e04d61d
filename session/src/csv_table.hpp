#pragma once
// The session's CSV tables (frames/index.csv, carm.csv, truth/ostia_2d.csv) and the
// recorder's journal, read row by row with errors "<file>:<line>: <field>: <what>".
// Shared by session_io.cpp and session_recorder.cpp, so both quote bad input the same way.
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"

namespace evar::session::detail {

/// A row longer than this is refused before it is split: the longest real one (a C-arm
/// sample, ten shortest-round-trip numbers) is under 300 bytes.
inline constexpr std::size_t kMaxRowBytes = 4096;
/// Bad input is quoted up to this many characters, so a huge field cannot make a huge log line.
inline constexpr std::size_t kMaxQuotedChars = 40;

[[noreturn]] inline void fail(const std::filesystem::path& file, std::size_t line, const std::string& what) {
  throw base::InputError(file.string() + (line ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

/// `text` for a message: at most kMaxQuotedChars characters (then "..."), anything but
/// printable ASCII shown as '?'.
inline std::string limited(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size() && i < kMaxQuotedChars; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    out += c >= 0x20 && c < 0x7f ? static_cast<char>(c) : '?';
  }
  if (text.size() > kMaxQuotedChars) out += "...";
  return out;
}

/// The same in quotes.
inline std::string quote(std::string_view text) {
  std::string out = "'";  // in steps: g++ 12 warns falsely (-Wrestrict) on "'" + std::string
  out += limited(text);
  out += '\'';
  return out;
}

/// The shortest text that reads back to the same double.
inline std::string exact(double v) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  if (ec != std::errc()) throw std::runtime_error("cannot format a number");
  return std::string(buf, end);
}

/// Whether a table's first line (without its line end) is `header`: for tables whose newer
/// form adds a column (carm.csv's zoom_mode), read either way.
/// A file that cannot be read is not: for_each_row then says why.
inline bool first_line_is(const std::filesystem::path& file, std::string_view header) {
  std::ifstream in(file, std::ios::binary);
  std::string text(header.size() + 2, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  std::string_view line(text);
  line = line.substr(0, line.find('\n'));
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line == header;
}

/// What to make of a last line with no newline: in a session it means the file was cut
/// (an error); in the recorder's journal it is the row the kill interrupted (skipped).
enum class CutLastLine { Refuse, Skip };

/// Calls row(line number, fields) for every non-empty line after the header, checking the
/// header, the row length and the field count; lines end in LF or CRLF. Returns whether a
/// cut last line was skipped.
template <class Row>
bool for_each_row(const std::filesystem::path& file, const char* header, std::size_t fields, CutLastLine cut, Row row) {
  const std::string text = base::read_input_file(file, base::kTableLimit);
  std::size_t start = 0, line = 0;
  bool skipped = false;
  while (start < text.size() || line == 0) {
    std::size_t end = text.find('\n', start);
    ++line;
    if (end == std::string::npos) {
      // Only the last line can lack its newline; an empty file is one empty, cut line.
      if (cut == CutLastLine::Skip && line > 1) {
        skipped = true;
        break;
      }
      if (!text.empty())
        fail(file, line, "cut short: the last line does not end with a newline (the file was cut or is still being written)");
      end = text.size();
    }
    if (end - start > kMaxRowBytes)
      fail(file, line, "a line of " + std::to_string(end - start) + " bytes; rows are at most " + std::to_string(kMaxRowBytes));
    std::string_view content(text.data() + start, end - start);
    if (!content.empty() && content.back() == '\r') content.remove_suffix(1);
    start = end + 1;
    if (line == 1) {
      if (content != header) fail(file, 1, std::string("header: expected '") + header + "', found " + quote(content));
      continue;
    }
    if (content.empty()) continue;
    std::vector<std::string> f;
    for (std::size_t from = 0;;) {
      const std::size_t comma = content.find(',', from);
      f.emplace_back(content.substr(from, comma == std::string_view::npos ? std::string_view::npos : comma - from));
      if (comma == std::string_view::npos) break;
      from = comma + 1;
    }
    if (f.size() != fields)
      fail(file, line, "expected " + std::to_string(fields) + " fields, found " + std::to_string(f.size()));
    row(line, f);
  }
  return skipped;
}

template <class T>
T number(const std::filesystem::path& file, std::size_t line, const char* field, const std::string& text) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty())
    fail(file, line, std::string(field) + ": " + quote(text) + " is not a number");
  if constexpr (std::is_floating_point_v<T>)
    if (!std::isfinite(value)) fail(file, line, std::string(field) + ": " + quote(text) + " is not finite");
  return value;
}

inline bool flag(const std::filesystem::path& file, std::size_t line, const char* field, const std::string& text) {
  if (text == "0") return false;
  if (text == "1") return true;
  fail(file, line, std::string(field) + ": " + quote(text) + " (expected 0 or 1)");
}

}  // namespace evar::session::detail

// Strict CSV reading and writing with errors that name the file and line.
//
// Comma-separated, first non-comment line is the header, '#' starts a comment line, fields may be
// double-quoted ("a,b" and "" for a quote). Blank lines are skipped. Every row must have as many
// fields as the header. A UTF-8 byte order mark at the start of the file is ignored.
#pragma once

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "epiloc/core/output_file.h"

namespace epiloc {

// Parses a whole field as a finite double / integer; throws Error naming `where` otherwise.
double ParseDouble(const std::string& text, const std::string& where);
int64_t ParseInt(const std::string& text, const std::string& where);
// Splits one CSV line into fields (quotes handled, no trailing newline).
std::vector<std::string> SplitCsvLine(const std::string& line);
// Leading and trailing white space removed.
std::string Trim(const std::string& text);

// Longest line ReadLine accepts: far beyond any text line epiloc reads, far below the memory a
// file without line breaks (/dev/zero, a binary file given as text) would take.
constexpr size_t kMaxLineBytes = size_t{1} << 20;

// std::getline for the text files epiloc reads, bounded: a line longer than kMaxLineBytes throws
// Error "<path>:<line_number>: line longer than ... bytes" (line_number < 1: the path alone).
// Returns false, with failbit set, when nothing was left to read; a last line without a newline
// is returned with eofbit set, as std::getline does.
bool ReadLine(std::istream& in, std::string& line, const std::string& path, int64_t line_number);

class CsvReader {
 public:
  // Opens `path` and reads its header; throws Error if it cannot be read or has no header.
  explicit CsvReader(const std::string& path);

  const std::string& path() const { return path_; }
  const std::vector<std::string>& header() const { return header_; }
  bool HasColumn(const std::string& name) const;
  // Throws Error "<path>: missing column '<name>'" when absent.
  void RequireColumns(const std::vector<std::string>& names) const;

  // Reads the next row; false at the end of the file.
  bool Next();
  // The same for a file another program is still appending to: only lines ended by a newline
  // are read (a partial last line is left for later); false when no complete row is available
  // yet. May be called again for the rows appended since.
  bool NextAppended();
  // Line number (1-based) of the current row, for messages.
  int64_t line() const { return line_; }
  // "path:line", the place of the current row.
  std::string where() const;

  // Field of the current row by column name; throws Error naming file and line if the column is
  // missing or the value does not parse.
  const std::string& Get(const std::string& column) const;
  double GetDouble(const std::string& column) const;
  int64_t GetInt(const std::string& column) const;
  // Empty field or absent column -> nullopt.
  std::optional<double> GetOptionalDouble(const std::string& column) const;

 private:
  std::string path_;
  std::ifstream in_;
  std::vector<std::string> header_;
  std::unordered_map<std::string, size_t> column_index_;
  std::vector<std::string> fields_;
  int64_t line_ = 0;
  // Takes `text` (line line_) as the current row; false for a blank or comment line.
  bool TakeLine(const std::string& text);
};

// Writes a header and rows; values are formatted by the caller. Throws Error on I/O failure.
// A file is written under a temporary name beside `path` and renamed to `path` by Close() (or the
// destructor), so it appears complete or not at all; destroyed while an exception propagates, the
// writer leaves no file. Standard output gets the rows as they are written.
class CsvWriter {
 public:
  // Opens `path` ("-": standard output) and writes the header.
  CsvWriter(const std::string& path, const std::vector<std::string>& header);
  void WriteRow(const std::vector<std::string>& fields);
  // Hands the rows written so far to the file (or the reader of standard output); throws Error
  // if writing failed.
  void Flush();
  // Flushes and checks the stream, then renames the file into place; called by the destructor too
  // (which does not throw, and discards the file when destroyed by an exception).
  void Close();
  ~CsvWriter();

 private:
  std::string path_;
  std::unique_ptr<AtomicFile> atomic_;  // null for standard output
  int uncaught_exceptions_;             // at construction: tells unwinding from a normal end
  std::ofstream file_;
  std::ostream* out_ = nullptr;  // file_ or std::cout; null once closed
  size_t num_columns_;
};

// Quotes a field if it holds a comma, quote or newline.
std::string CsvEscape(const std::string& field);
// Shortest text that reads back as the same double ("%.17g" trimmed), "" for NaN.
std::string FormatDouble(double value);
// Fixed number of decimals, "" for NaN.
std::string FormatFixed(double value, int decimals);

}  // namespace epiloc

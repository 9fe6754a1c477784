#include "epiloc/core/csv.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <iostream>

#include <fmt/format.h>

#include "epiloc/core/error.h"

namespace epiloc {

std::string Trim(const std::string& text) {
  const auto begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return "";
  const auto end = text.find_last_not_of(" \t\r\n");
  return text.substr(begin, end - begin + 1);
}

double ParseDouble(const std::string& text, const std::string& where) {
  const std::string trimmed = Trim(text);
  if (trimmed.empty()) Throw("{}: empty value where a number is expected", where);
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(trimmed.c_str(), &end);
  if (end != trimmed.c_str() + trimmed.size() || errno == ERANGE) {
    Throw("{}: '{}' is not a number", where, trimmed);
  }
  if (!std::isfinite(value)) Throw("{}: '{}' is not a finite number", where, trimmed);
  return value;
}

int64_t ParseInt(const std::string& text, const std::string& where) {
  const std::string trimmed = Trim(text);
  if (trimmed.empty()) Throw("{}: empty value where an integer is expected", where);
  errno = 0;
  char* end = nullptr;
  const long long value = std::strtoll(trimmed.c_str(), &end, 10);
  if (end != trimmed.c_str() + trimmed.size() || errno == ERANGE) {
    Throw("{}: '{}' is not an integer", where, trimmed);
  }
  return value;
}

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  bool quoted = false;
  // Spaces inside quotes are data; only those around quotes are trimmed.
  bool was_quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      if (!was_quoted) field = Trim(field);
      quoted = was_quoted = true;
    } else if (c == ',') {
      fields.push_back(was_quoted ? field : Trim(field));
      field.clear();
      was_quoted = false;
    } else if (c != '\r' && !(was_quoted && (c == ' ' || c == '\t'))) {
      field += c;
    }
  }
  fields.push_back(was_quoted ? field : Trim(field));
  return fields;
}

CsvReader::CsvReader(const std::string& path) : path_(path), in_(path) {
  if (!in_) Throw("{}: cannot open file", path);
  if (!Next()) Throw("{}: empty file, expected a CSV header", path);
  header_ = fields_;
  for (size_t i = 0; i < header_.size(); ++i) {
    if (header_[i].empty()) Throw("{}: empty column name in header", Where(path_, line_));
    if (!column_index_.emplace(header_[i], i).second) {
      Throw("{}: column '{}' appears twice", Where(path_, line_), header_[i]);
    }
  }
}

bool CsvReader::HasColumn(const std::string& name) const { return column_index_.count(name) > 0; }

void CsvReader::RequireColumns(const std::vector<std::string>& names) const {
  for (const auto& name : names) {
    if (!HasColumn(name)) Throw("{}: missing column '{}'", path_, name);
  }
}

bool CsvReader::TakeLine(const std::string& raw) {
  // A UTF-8 byte order mark (spreadsheet exports) before the first line is not part of the header.
  static const std::string kBom = "\xEF\xBB\xBF";
  const std::string& text =
      line_ == 1 && raw.compare(0, kBom.size(), kBom) == 0 ? raw.substr(kBom.size()) : raw;
  const std::string trimmed = Trim(text);
  if (trimmed.empty() || trimmed[0] == '#') return false;
  // A path is cut at a NUL byte by every file API: "images/1.png\0junk" read images/1.png.
  if (text.find('\0') != std::string::npos) {
    Throw("{}: a NUL byte in the line (a binary file?)", where());
  }
  fields_ = SplitCsvLine(text);
  if (!header_.empty() && fields_.size() != header_.size()) {
    Throw("{}: {} fields, the header has {}", where(), fields_.size(), header_.size());
  }
  return true;
}

bool ReadLine(std::istream& in, std::string& line, const std::string& path, int64_t line_number) {
  line.clear();
  const std::istream::sentry sentry(in, true);
  if (!sentry) return false;
  std::streambuf* buffer = in.rdbuf();
  for (;;) {
    const int c = buffer->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      in.setstate(line.empty() ? std::ios::eofbit | std::ios::failbit : std::ios::eofbit);
      return !line.empty();
    }
    if (c == '\n') return true;
    if (line.size() >= kMaxLineBytes) {
      Throw("{}: line longer than {} bytes (not a text file?)", Where(path, line_number),
            kMaxLineBytes);
    }
    line.push_back(static_cast<char>(c));
  }
}

bool CsvReader::Next() {
  std::string text;
  while (ReadLine(in_, text, path_, line_ + 1)) {
    ++line_;
    if (TakeLine(text)) return true;
  }
  if (in_.bad()) Throw("{}: read error", path_);
  return false;
}

bool CsvReader::NextAppended() {
  for (;;) {
    in_.clear();  // an earlier end of file: the file may have grown since
    const std::streampos start = in_.tellg();
    std::string text;
    if (!ReadLine(in_, text, path_, line_ + 1) || in_.eof()) {
      // Nothing, or a line still being written: read it again once it is complete.
      if (in_.bad()) Throw("{}: read error", path_);
      in_.clear();
      in_.seekg(start);
      return false;
    }
    ++line_;
    if (TakeLine(text)) return true;
  }
}

std::string CsvReader::where() const { return Where(path_, line_); }

const std::string& CsvReader::Get(const std::string& column) const {
  const auto it = column_index_.find(column);
  if (it == column_index_.end()) Throw("{}: missing column '{}'", path_, column);
  return fields_.at(it->second);
}

double CsvReader::GetDouble(const std::string& column) const {
  return ParseDouble(Get(column), fmt::format("{} column '{}'", where(), column));
}

int64_t CsvReader::GetInt(const std::string& column) const {
  return ParseInt(Get(column), fmt::format("{} column '{}'", where(), column));
}

std::optional<double> CsvReader::GetOptionalDouble(const std::string& column) const {
  if (!HasColumn(column) || Get(column).empty()) return std::nullopt;
  return GetDouble(column);
}

std::string CsvEscape(const std::string& field) {
  // Quoted too when it has spaces at either end, which the reader trims from
  // unquoted fields.
  const bool plain = field.find_first_of(",\"\n\r") == std::string::npos;
  if (plain && field == Trim(field)) return field;
  std::string quoted = "\"";
  for (const char c : field) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

std::string FormatDouble(double value) {
  if (std::isnan(value)) return "";
  return fmt::format("{}", value);  // fmt prints the shortest round-tripping form
}

std::string FormatFixed(double value, int decimals) {
  if (std::isnan(value)) return "";
  return fmt::format("{:.{}f}", value, decimals);
}

CsvWriter::CsvWriter(const std::string& path, const std::vector<std::string>& header)
    : path_(path == "-" ? "standard output" : path),
      uncaught_exceptions_(std::uncaught_exceptions()),
      num_columns_(header.size()) {
  if (path == "-") {
    out_ = &std::cout;
  } else {
    atomic_ = std::make_unique<AtomicFile>(path);
    file_.open(atomic_->temp_path());
    if (!file_) Throw("{}: cannot open for writing", path);
    out_ = &file_;
  }
  WriteRow(header);
}

void CsvWriter::WriteRow(const std::vector<std::string>& fields) {
  if (fields.size() != num_columns_) {
    Throw("{}: internal error, row of {} fields for {} columns", path_, fields.size(),
          num_columns_);
  }
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i > 0) *out_ << ',';
    *out_ << CsvEscape(fields[i]);
  }
  *out_ << '\n';
}

void CsvWriter::Flush() {
  if (!out_) return;
  out_->flush();
  if (!*out_) Throw("{}: write failed", path_);
}

void CsvWriter::Close() {
  if (!out_) return;
  out_->flush();
  bool ok = static_cast<bool>(*out_);
  if (file_.is_open()) {
    file_.close();
    ok = ok && !file_.fail();
  }
  out_ = nullptr;
  if (!ok) {
    if (atomic_) atomic_->Discard();
    Throw("{}: write failed", path_);
  }
  if (atomic_) atomic_->Commit();
}

CsvWriter::~CsvWriter() {
  if (atomic_ && std::uncaught_exceptions() > uncaught_exceptions_) {
    if (file_.is_open()) file_.close();
    atomic_->Discard();  // a failed run leaves no partial file
    return;
  }
  try {
    Close();
  } catch (const Error&) {
  }
}

}  // namespace epiloc

// Output files that appear complete or not at all, and the checks a command makes on its output
// paths before the work starts (an output must not be one of the inputs, its folder must accept
// a new file).
#pragma once

#include <exception>
#include <fstream>
#include <string>
#include <vector>

namespace epiloc {

// True if `a` and `b` name the same file: std::filesystem::equivalent when both exist (symbolic
// and hard links), else the same weakly canonical path. False for an empty path.
bool SameFile(const std::string& a, const std::string& b);

// True if `path` is the folder `folder` or lies inside it, symbolic links and ".." resolved in
// both (weakly canonical: the part that exists).
bool IsWithinFolder(const std::string& path, const std::string& folder);

// A path given to a command and the option that gave it, e.g. {"--db", "route.sqlite"}.
struct NamedPath {
  std::string option;
  std::string path;
  bool folder_contents = false;  // an input folder whose files are all inputs (an image folder):
                                 // an output inside it is refused too
};

// Throws Error "--out R.sqlite is the same file as the input --db R.sqlite: refusing to overwrite
// an input" when an output is one of the inputs (or two outputs are the same file), then checks
// every output with CheckWritable. Empty paths and "-" (standard output) are skipped.
void CheckOutputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

// Throws Error naming `option` and `path` unless a file `path` can be written: its folder exists
// and accepts a new file (a probe file is created and removed), and `path` is not a folder.
void CheckWritable(const std::string& path, const std::string& option);

// A file written under a temporary name in its own folder and renamed over `path` on Commit(),
// so a reader never sees a partial file and a failure leaves the previous file (or none).
// Destroyed without Commit(), the temporary file is removed. A symbolic link stays a link (the
// file it points to is replaced). A device, FIFO or socket (/dev/null, /dev/full, a named pipe)
// is written in place: temp_path() is `path` and Commit() renames nothing. SIGINT, SIGTERM and
// SIGHUP (when not ignored or handled otherwise) remove the temporary files of the live
// AtomicFiles before the process dies of the signal.
class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  const std::string& path() const { return path_; }
  // Where to write: ".<name>.tmp-<pid>-<n><extension>" beside `path` (same extension, so that
  // writers choosing an encoder by extension, such as cv::imwrite, still work).
  const std::string& temp_path() const { return temp_path_; }
  // Renames the temporary file to `path`; throws Error (and removes it) if that fails.
  void Commit();
  // Removes the temporary file; the destination is left as it was.
  void Discard();

 private:
  std::string path_;
  std::string temp_path_;
  bool in_place_ = false;  // a device or FIFO: written directly
  bool done_ = false;
};

// An output file stream on an AtomicFile: write, then Commit() (flushes, checks the stream, renames).
// Throws Error on open and write failures, naming `path`. Destroyed without Commit(), nothing
// appears at `path`.
class AtomicOfstream {
 public:
  explicit AtomicOfstream(const std::string& path,
                          std::ios::openmode mode = std::ios::out | std::ios::trunc);
  std::ofstream& stream() { return out_; }
  template <typename T>
  AtomicOfstream& operator<<(const T& value) {
    out_ << value;
    return *this;
  }
  void Commit();

 private:
  AtomicFile file_;
  std::ofstream out_;
};

}  // namespace epiloc

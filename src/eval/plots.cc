#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/eval/report.h"

namespace epiloc {
namespace fs = std::filesystem;
namespace {

// Single-quoted for /bin/sh.
std::string ShellQuote(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  return quoted + "'";
}

class DataFile {
 public:
  explicit DataFile(const fs::path& path) : path_(path), out_(path) {
    if (!out_) Throw("{}: cannot open for writing", path.string());
  }
  void Row(double x, double y) { out_ << fmt::format("{:.6f} {:.6f}\n", x, y); }
  void Close() {
    out_.close();
    if (!out_) Throw("{}: write failed", path_.string());
  }

 private:
  fs::path path_;
  std::ofstream out_;
};

// Distinct line colours (gnuplot's default cycle is hard to read for many methods).
const std::vector<std::string> kColours = {"#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd",
                                           "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f",
                                           "#393b79", "#637939", "#843c39"};

std::string Colour(size_t i) { return kColours[i % kColours.size()]; }

// Writes the data files; returns the evaluated methods (those with frames) in table order.
std::vector<std::string> WriteData(const Evaluation& eval, const fs::path& dir) {
  std::vector<std::string> methods;
  for (const auto& m : eval.methods) {
    if (m.frames.empty()) continue;
    methods.push_back(m.method);
    std::vector<double> abs_errors;
    for (const auto& f : m.frames) abs_errors.push_back(std::abs(f.along_track_m));
    std::sort(abs_errors.begin(), abs_errors.end());
    DataFile cdf(dir / ("cdf_" + m.method + ".dat"));
    cdf.Row(0.0, 0.0);
    for (size_t i = 0; i < abs_errors.size(); ++i) {
      cdf.Row(abs_errors[i], static_cast<double>(i + 1) / static_cast<double>(abs_errors.size()));
    }
    cdf.Close();
    std::vector<FrameError> by_s = m.frames;
    std::sort(by_s.begin(), by_s.end(),
              [](const FrameError& a, const FrameError& b) { return a.truth_s_m < b.truth_s_m; });
    DataFile along(dir / ("along_" + m.method + ".dat"));
    for (const auto& f : by_s) along.Row(f.truth_s_m, f.along_track_m);
    along.Close();
    DataFile top(dir / ("top_" + m.method + ".dat"));
    for (const auto& f : m.frames) top.Row(f.estimate_in_enu.x(), f.estimate_in_enu.y());
    top.Close();
  }
  DataFile truth(dir / "truth.dat");
  for (const auto& p : eval.truth_in_enu) truth.Row(p.x(), p.y());
  truth.Close();
  DataFile route(dir / "route.dat");
  for (const auto& p : eval.route.points_in_enu) route.Row(p.x(), p.y());
  route.Close();
  return methods;
}

// The gnuplot script drawing the three plots with `terminal` into files of extension `ext`.
std::string Script(const std::vector<std::string>& methods,
                   const std::string& terminal,
                   const std::string& ext) {
  std::string s = "# Written by epiloc evaluate; run in this folder: gnuplot " +
                  std::string(ext == "svg" ? "plots.gp" : "plots_png.gp") + "\n";
  s += "set terminal " + terminal + "\nset termoption noenhanced\nset grid\n";
  s += "set style line 100 lc rgb '#000000' lw 2\n";
  for (size_t i = 0; i < methods.size(); ++i) {
    s += fmt::format("set style line {} lc rgb '{}' lw 2 pt 7 ps 0.5\n", i + 1, Colour(i));
  }
  const auto plot = [&](const std::string& prefix, const std::string& style) {
    std::vector<std::string> parts;
    for (size_t i = 0; i < methods.size(); ++i) {
      parts.push_back(fmt::format("'{}{}.dat' using 1:2 {} ls {} title '{}'", prefix, methods[i],
                                  style, i + 1, methods[i]));
    }
    return fmt::format("{}", fmt::join(parts, ", \\\n     "));
  };
  s += fmt::format("\nset output 'cdf.{}'\n", ext);
  s += "set title 'Cumulative distribution of the absolute along-track error'\n";
  s += "set xlabel 'absolute along-track error [m]'\nset ylabel 'share of frames'\n";
  s += "set xrange [0:*]\nset yrange [0:1.02]\nset key bottom right\n";
  s += "plot " + plot("cdf_", "with steps") + "\n";
  s += fmt::format("\nset output 'along_route.{}'\n", ext);
  s += "set title 'Signed along-track error along the route (+ = estimate ahead)'\n";
  s += "set xlabel 'along-route distance of the ground truth s [m]'\n";
  s += "set ylabel 'along-track error [m]'\nset autoscale\nset key top right\n";
  s += "plot 0 with lines lc rgb '#888888' notitle, \\\n     " +
       plot("along_", "with linespoints") + "\n";
  s += fmt::format("\nset output 'top_view.{}'\n", ext);
  s += "set title 'Top view (local ENU)'\nset xlabel 'east [m]'\nset ylabel 'north [m]'\n";
  s += "set autoscale\nset size ratio -1\nset key outside bottom center horizontal\n";
  s += "plot 'route.dat' using 1:2 with lines lc rgb '#aaaaaa' lw 6 title 'route', \\\n"
       "     'truth.dat' using 1:2 with lines ls 100 title 'ground truth', \\\n"
       "     'truth.dat' every ::0::0 using 1:2 with points pt 5 ps 1.5 lc rgb '#000000' "
       "title 'start', \\\n     " +
       plot("top_", "with points") + "\n";
  s += "set output\n";
  return s;
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) Throw("{}: write failed", path.string());
}

// Runs gnuplot on `script` inside `dir`; its output goes to `script`.log. True on success.
bool RunGnuplot(const std::string& gnuplot, const fs::path& dir, const std::string& script) {
  const std::string command =
      fmt::format("cd {} && {} {} > {} 2>&1", ShellQuote(dir.string()), ShellQuote(gnuplot),
                  ShellQuote(script), ShellQuote(script + ".log"));
  return std::system(command.c_str()) == 0;
}

}  // namespace

void ReportOptions::Check() const {
  EPILOC_CHECK(!gnuplot.empty(), "the gnuplot executable name is empty");
}

bool GnuplotAvailable(const std::string& gnuplot) {
  const std::string command = ShellQuote(gnuplot) + " --version > /dev/null 2>&1";
  return std::system(command.c_str()) == 0;
}

PlotFiles WritePlots(const Evaluation& eval, const std::string& dir, const ReportOptions& options) {
  options.Check();
  if (!GnuplotAvailable(options.gnuplot)) {
    Throw(
        "gnuplot not found ('{}' does not run): install gnuplot-nox (apt-get install "
        "gnuplot-nox) for the report's plots",
        options.gnuplot);
  }
  const fs::path folder = fs::absolute(dir);
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) Throw("{}: cannot create the plot folder: {}", folder.string(), error.message());
  const std::vector<std::string> methods = WriteData(eval, folder);
  if (methods.empty()) Throw("{}: no evaluated frames to plot", folder.string());

  PlotFiles files;
  WriteText(
      folder / "plots.gp",
      Script(methods, "svg size 900,560 dynamic font 'sans,13' background rgb 'white'", "svg"));
  if (!RunGnuplot(options.gnuplot, folder, "plots.gp")) {
    Throw("{}: gnuplot failed, see {}", (folder / "plots.gp").string(),
          (folder / "plots.gp.log").string());
  }
  for (const char* name : {"cdf", "along_route", "top_view"}) {
    files.svg.push_back((folder / (std::string(name) + ".svg")).string());
  }
  if (options.png) {
    WriteText(
        folder / "plots_png.gp",
        Script(methods, "pngcairo size 1000,625 font 'sans,11' background rgb 'white'", "png"));
    if (RunGnuplot(options.gnuplot, folder, "plots_png.gp")) {
      for (const char* name : {"cdf", "along_route", "top_view"}) {
        files.png.push_back((folder / (std::string(name) + ".png")).string());
      }
    } else {
      spdlog::warn("{}: gnuplot could not draw PNGs (no pngcairo terminal?); SVGs only",
                   (folder / "plots_png.gp").string());
    }
  }
  return files;
}

}  // namespace epiloc

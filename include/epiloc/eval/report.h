// Presentation of an Evaluation: text tables (stdout), JSON, gnuplot plots and a self-contained
// HTML report.
#pragma once

#include <string>
#include <vector>

#include "epiloc/eval/evaluate.h"

namespace epiloc {

// The tables `epiloc evaluate` prints, laid out like Table 1 of Kyutoku et al.: one column per
// method, rows Min, Max, Mean|e|, Bias, Std, Median|e|, RMSE, P95|e| (metres), <=0.1m ... <=2m
// (percent of evaluated frames), then the frame counts (rows, ok, lost, off_route, rejected,
// skipped, unmatched, evaluated). The along-track table comes first, then a compact one (Mean|e|,
// RMSE, P95|e|, <=0.5m, <=1m) for cross-track, horizontal, vertical and 3-D error. Empty cells
// ("-") where a method has no evaluated frame.
std::string FormatEvaluationTables(const Evaluation& eval);

// All metrics of all methods, counts and unmatched frames as JSON text (schema in the .cc; NaN
// written as null).
std::string EvaluationJson(const Evaluation& eval);
void WriteEvaluationJson(const Evaluation& eval, const std::string& path);
// One row per evaluated frame and method: truth and estimated s, the errors (along-track,
// cross-track, horizontal, vertical, 3-D in metres, rotation in degrees) and the row's sigmas
// (empty where the method gives none). "-": standard output.
void WriteFrameErrorsCsv(const Evaluation& eval, const std::string& path);

struct ReportOptions {
  std::string gnuplot = "gnuplot";  // gnuplot executable (Debian: apt-get install gnuplot-nox)
  bool png = true;                  // also render PNGs (pngcairo; a warning if unavailable)

  void Check() const;
};

// The plots written by WritePlots, in report order.
struct PlotFiles {
  std::vector<std::string> svg;  // cdf.svg, along_route.svg, top_view.svg
  std::vector<std::string> png;  // the same as PNG (empty when not rendered)
};

// True if `gnuplot` runs ("gnuplot --version" exits with 0).
bool GnuplotAvailable(const std::string& gnuplot);

// Writes into `dir` (created): the data files (*.dat), plots.gp (SVG) and plots_png.gp, and runs
// gnuplot on them:
//  - cdf: share of frames (y) whose absolute along-track error is <= x metres, every method
//    (Kyutoku et al. Fig. 8);
//  - along_route: signed along-track error (y) against the truth's along-route distance (x);
//  - top_view: ground truth, route and every method's estimates, east/north metres, equal scale.
// Throws Error "gnuplot not found ... install gnuplot-nox" if it does not run, or naming the
// script if gnuplot fails.
PlotFiles WritePlots(const Evaluation& eval, const std::string& dir, const ReportOptions& options);

// Writes a self-contained HTML report (inputs, tables, the SVGs inlined; no external files,
// scripts or styles) to `html_path`; the plots go to "<html_path without .html>_files/".
void WriteHtmlReport(const Evaluation& eval,
                     const std::string& html_path,
                     const ReportOptions& options);

}  // namespace epiloc

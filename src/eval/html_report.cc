#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/eval/report.h"
#include "report_internal.h"

namespace epiloc {
namespace fs = std::filesystem;
namespace {

std::string Escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

void ReplaceAll(std::string& text, const std::string& from, const std::string& to) {
  for (size_t pos = text.find(from); pos != std::string::npos;
       pos = text.find(from, pos + to.size())) {
    text.replace(pos, from.size(), to);
  }
}

// The <svg> element of a gnuplot SVG file, ready to inline: the XML prolog dropped and element
// ids prefixed with `prefix` so that several plots in one page do not share clip paths.
std::string InlineSvg(const std::string& path, const std::string& prefix) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot read the plot", path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  std::string svg = buffer.str();
  const size_t start = svg.find("<svg");
  if (start == std::string::npos) Throw("{}: not an SVG file", path);
  svg = svg.substr(start);
  for (const char* quote : {"'", "\""}) {
    ReplaceAll(svg, std::string("id=") + quote, std::string("id=") + quote + prefix);
    ReplaceAll(svg, std::string("href=") + quote + "#",
               std::string("href=") + quote + "#" + prefix);
  }
  ReplaceAll(svg, "url(#", "url(#" + prefix);
  return svg;
}

std::string HtmlTable(const std::string& caption,
                      const std::vector<TableRow>& rows,
                      const Evaluation& eval) {
  std::string html =
      "<table class=\"stats\">\n<caption>" + Escape(caption) + "</caption>\n<tr><th></th>";
  for (const auto& m : eval.methods) html += "<th>" + Escape(m.method) + "</th>";
  html += "</tr>\n";
  for (const auto& row : rows) {
    if (row.cells.empty()) {
      html += fmt::format("<tr class=\"section\"><th colspan=\"{}\">{}</th></tr>\n",
                          eval.methods.size() + 1, Escape(row.label));
      continue;
    }
    html += "<tr><th>" + Escape(row.label) + "</th>";
    for (const auto& cell : row.cells) html += "<td>" + Escape(cell) + "</td>";
    html += "</tr>\n";
  }
  return html + "</table>\n";
}

constexpr const char* kStyle = R"(
body { font-family: sans-serif; margin: 2em; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0 1em 0; }
caption { text-align: left; font-weight: bold; padding: 0.3em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.7em; }
td { text-align: right; font-family: monospace; }
th { text-align: left; background: #f4f4f4; }
tr.section th { background: #e4e4ec; }
table.inputs td { text-align: left; }
figure { margin: 1em 0; } figcaption { color: #555; font-size: 0.9em; }
svg { max-width: 100%; height: auto; }
.warning { color: #a60; }
)";

}  // namespace

void WriteHtmlReport(const Evaluation& eval,
                     const std::string& html_path,
                     const ReportOptions& options) {
  CreateParentDirectory(html_path);
  fs::path plot_dir(html_path);
  plot_dir.replace_extension();
  plot_dir += "_files";
  const PlotFiles plots = WritePlots(eval, plot_dir.string(), options);

  std::string html = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  html += "<title>epiloc evaluation</title>\n<style>" + std::string(kStyle) + "</style>\n</head>\n";
  html += "<body>\n<h1>epiloc evaluation</h1>\n<h2>Inputs</h2>\n<table class=\"inputs\">\n";
  for (const auto& [label, value] : eval.inputs) {
    html += "<tr><th>" + Escape(label) + "</th><td>" + Escape(value) + "</td></tr>\n";
  }
  html += "</table>\n";
  if (!eval.warnings.empty()) {
    html += "<h2>Warnings</h2>\n<ul>\n";
    for (const auto& w : eval.warnings) html += "<li class=\"warning\">" + Escape(w) + "</li>\n";
    html += "</ul>\n";
  }
  html += "<h2>Errors</h2>\n";
  html +=
      "<p>Statistics over the evaluated frames (status ok with ground truth). Min, Max, Bias "
      "and Std are of the signed error (Std: population), Mean|e|, Median|e| and P95|e| of its "
      "absolute value; percentiles interpolate linearly between order statistics (numpy's "
      "default). Frames not localized are counted, not included.</p>\n";
  html += HtmlTable(AlongTrackTitle(), AlongTrackRows(eval), eval);
  html += HtmlTable(OtherErrorsTitle(), OtherErrorRows(eval), eval);
  html += "<h2>Plots</h2>\n";
  const std::vector<std::string> captions = {
      "Share of frames whose absolute along-track error is at most x (Kyutoku et al., Fig. 8).",
      "Signed along-track error against the ground truth's along-route distance.",
      "Top view in the local ENU frame (equal axis scales): route, ground truth and estimates."};
  for (size_t i = 0; i < plots.svg.size(); ++i) {
    html += "<figure>\n" + InlineSvg(plots.svg[i], fmt::format("p{}_", i)) + "\n<figcaption>" +
            Escape(captions[i]) + "</figcaption>\n</figure>\n";
  }
  html += "<p>Plot data and gnuplot scripts: " + Escape(plot_dir.string()) + "</p>\n";
  html += "</body>\n</html>\n";

  AtomicOfstream out(html_path);
  out << html;
  out.Commit();
}

}  // namespace epiloc

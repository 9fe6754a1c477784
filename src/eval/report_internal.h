// Table rows shared by the text and HTML reports (private to the eval module).
#pragma once

#include <string>
#include <vector>

#include "epiloc/eval/evaluate.h"

namespace epiloc {

// One row of a report table: a label and one formatted cell per method (no cells: a heading).
struct TableRow {
  std::string label;
  std::vector<std::string> cells;
};

std::vector<TableRow> AlongTrackRows(const Evaluation& eval);
std::vector<TableRow> OtherErrorRows(const Evaluation& eval);
std::string AlongTrackTitle();
std::string OtherErrorsTitle();
// Creates the folder `path` goes into; throws Error naming it if that fails.
void CreateParentDirectory(const std::string& path);

}  // namespace epiloc

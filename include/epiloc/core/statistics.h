// Order statistics of samples, shared by the modules that summarise residuals and errors.
#pragma once

#include <vector>

namespace epiloc {

// The median: the middle value of an odd count, the mean of the two middle values of an even
// count; 0 for no values. Takes a copy (partially reordered, O(n)).
double Median(std::vector<double> values);

// The upper median: the value at index n / 2 of the sorted values (of an even count the larger
// of the two middle ones), always one of the values themselves; 0 for no values.
double UpperMedian(std::vector<double> values);

}  // namespace epiloc

#pragma once
/// Timestamp association between two sorted time lists, the TUM benchmark's rule: every pair
/// closer than max_dt_s is a candidate; candidates are taken closest first, each index used at
/// most once (one-to-one); the result is sorted by the first list.
#include <utility>
#include <vector>

namespace ltlo::io {

/// Index pairs (i into a_s, j into b_s) with |a_s[i] - b_s[j]| <= max_dt_s, one-to-one.
/// Both lists must be sorted ascending.
std::vector<std::pair<int, int>> associateTimestamps(const std::vector<double>& a_s,
                                                     const std::vector<double>& b_s,
                                                     double max_dt_s);

}  // namespace ltlo::io

#include "ltlo/io/associate.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "ltlo/core/assert.h"

namespace ltlo::io {

std::vector<std::pair<int, int>> associateTimestamps(const std::vector<double>& a_s,
                                                     const std::vector<double>& b_s,
                                                     double max_dt_s) {
  LTLO_ASSERT(std::is_sorted(a_s.begin(), a_s.end()), "first timestamp list is not sorted");
  LTLO_ASSERT(std::is_sorted(b_s.begin(), b_s.end()), "second timestamp list is not sorted");
  // Candidates: for each a, the b inside the window (a sliding window over sorted b keeps this
  // linear in the number of candidates instead of |a| * |b|).
  std::vector<std::tuple<double, int, int>> candidates;  // (|dt|, i, j)
  size_t window_begin = 0;
  for (size_t i = 0; i < a_s.size(); ++i) {
    while (window_begin < b_s.size() && b_s[window_begin] < a_s[i] - max_dt_s) ++window_begin;
    for (size_t j = window_begin; j < b_s.size() && b_s[j] <= a_s[i] + max_dt_s; ++j) {
      candidates.emplace_back(std::abs(a_s[i] - b_s[j]), static_cast<int>(i), static_cast<int>(j));
    }
  }
  std::sort(candidates.begin(), candidates.end());  // closest first; ties by index, deterministic
  std::vector<bool> a_used(a_s.size(), false);
  std::vector<bool> b_used(b_s.size(), false);
  std::vector<std::pair<int, int>> matches;
  for (const auto& [dt_s, i, j] : candidates) {
    if (a_used[i] || b_used[j]) continue;
    a_used[i] = true;
    b_used[j] = true;
    matches.emplace_back(i, j);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

}  // namespace ltlo::io

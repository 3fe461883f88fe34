#include "bow/bow_vector.h"

#include <algorithm>

namespace bow {

double l1Score(const BowVector& a, const BowVector& b) {
  // For non-negative vectors with |a|_1 = |b|_1 = 1:
  //   1 - 0.5 |a - b|_1 = 0.5 (|a|_1 + |b|_1 - |a - b|_1) = sum_i min(a_i, b_i),
  // so only the words present in both vectors contribute.
  double score = 0.0;
  auto ia = a.entries.begin();
  auto ib = b.entries.begin();
  while (ia != a.entries.end() && ib != b.entries.end()) {
    if (ia->first < ib->first) {
      ++ia;
    } else if (ib->first < ia->first) {
      ++ib;
    } else {
      score += std::min(ia->second, ib->second);
      ++ia;
      ++ib;
    }
  }
  return score;
}

}  // namespace bow

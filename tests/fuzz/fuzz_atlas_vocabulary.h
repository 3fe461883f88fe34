#pragma once
// The vocabulary fuzz_atlas loads its inputs with: small, trained in a few milliseconds from fixed
// random descriptors, so the regression atlases in regressions/fuzz_atlas/ (built with it) pass the
// vocabulary check and reach every section reader and the BoW rebuild.
#include <random>
#include <vector>

#include "bow/vocabulary.h"

namespace ltlo::fuzz {

inline bow::Vocabulary atlasFuzzVocabulary() {
  std::mt19937_64 rng(1);
  std::vector<std::vector<bow::Descriptor>> images(2);
  for (std::vector<bow::Descriptor>& image : images) {
    for (int i = 0; i < 100; ++i) image.push_back({rng(), rng(), rng(), rng()});
  }
  return bow::Vocabulary::train(images, bow::TrainOptions{3, 2, 3, 1, 1, 0, {}});
}

}  // namespace ltlo::fuzz

// Writes fuzz_atlas's vocabulary (fuzz_atlas_vocabulary.h) to a file, for `rgbd_inertial
// --vocabulary` when a regression atlas of fuzz_atlas is made again (tests/fuzz/CMakeLists.txt).
#include <iostream>

#include "fuzz_atlas_vocabulary.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: write_fuzz_atlas_vocabulary OUT.bin\n";
    return 2;
  }
  ltlo::fuzz::atlasFuzzVocabulary().save(argv[1]);
  return 0;
}

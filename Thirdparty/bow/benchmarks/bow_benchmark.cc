// bow benchmarks: BoW transform of 1000 descriptors, a query against 5,000 entries, loading.
// Uses the shipped vocabulary (Vocabulary/ltlo_orb_k10_L5.bin under $LTLO_SOURCE_DIR or the working
// directory) when present, otherwise trains a k = 10, L = 5 tree on synthetic descriptors.
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>

#include <benchmark/benchmark.h>

#include "bow/database.h"
#include "bow/vocabulary.h"

namespace {

std::vector<bow::Descriptor> noisyDraws(const std::vector<bow::Descriptor>& prototypes, int n, std::mt19937_64& rng) {
  std::vector<bow::Descriptor> out;
  for (int i = 0; i < n; ++i) {
    bow::Descriptor d = prototypes[rng() % prototypes.size()];
    for (int f = 0; f < 10; ++f) {
      const int bit = static_cast<int>(rng() % 256);
      d[bit / 64] ^= std::uint64_t{1} << (bit % 64);
    }
    out.push_back(d);
  }
  return out;
}

std::string shippedPath() {
  const char* root = std::getenv("LTLO_SOURCE_DIR");
  return std::string(root ? root : ".") + "/Vocabulary/ltlo_orb_k10_L5.bin";
}

struct Fixture {
  bow::Vocabulary vocabulary;
  std::vector<bow::Descriptor> prototypes;
  std::string source;
  Fixture() {
    std::mt19937_64 rng(1);
    for (int i = 0; i < 200000; ++i) prototypes.push_back({rng(), rng(), rng(), rng()});
    const std::string path = shippedPath();
    if (std::ifstream(path).good()) {
      vocabulary = bow::Vocabulary::load(path);
      source = path;
    } else {
      std::vector<std::vector<bow::Descriptor>> images;
      for (int i = 0; i < 300; ++i) images.push_back(noisyDraws(prototypes, 1000, rng));
      vocabulary = bow::Vocabulary::train(images, bow::TrainOptions{});
      source = "synthetic k=10 L=5";
    }
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void BM_Transform1000(benchmark::State& state) {
  const Fixture& f = fixture();
  std::mt19937_64 rng(2);
  const std::vector<bow::Descriptor> descriptors = noisyDraws(f.prototypes, 1000, rng);
  bow::BowVector v;
  bow::FeatureVector fv;
  for (auto _ : state) {
    f.vocabulary.transform(descriptors, &v, &fv, 2);
    benchmark::DoNotOptimize(v.entries.data());
  }
  state.SetLabel(f.source);
}
BENCHMARK(BM_Transform1000)->Unit(benchmark::kMillisecond);

void BM_Query5000(benchmark::State& state) {
  const Fixture& f = fixture();
  std::mt19937_64 rng(3);
  bow::Database db(f.vocabulary.numWords());
  std::vector<bow::BowVector> vectors;
  for (int i = 0; i < 5000; ++i) {
    bow::BowVector v;
    f.vocabulary.transform(noisyDraws(f.prototypes, 1000, rng), &v);
    db.add(v);
    if (i < 50) vectors.push_back(v);
  }
  std::size_t q = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(db.query(vectors[q++ % vectors.size()], 10));
  }
  state.SetLabel(f.source);
}
BENCHMARK(BM_Query5000)->Unit(benchmark::kMillisecond);

void BM_LoadShipped(benchmark::State& state) {
  const std::string path = shippedPath();
  if (!std::ifstream(path).good()) {
    state.SkipWithError(("no vocabulary at " + path).c_str());
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(bow::Vocabulary::load(path).numNodes());
}
BENCHMARK(BM_LoadShipped)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

#pragma once
// Shared by the libFuzzer targets: quiet logging (warnings per input would dominate the run time)
// and a per-process scratch file for readers that take a path.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "ltlo/core/log.h"

namespace ltlo::fuzz {

/// Logs only errors (call once from LLVMFuzzerInitialize).
inline void quietLogging() { log::setLevel(log::Level::kError); }

/// The input as text.
inline std::string asText(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// Writes the input to a scratch file of this process ("<tmp>/ltlo_fuzz_<tag>_<pid><suffix>")
/// and returns its path: readers that take a path see exactly the fuzzer's bytes.
inline std::string writeScratchFile(const std::string& tag, const std::string& suffix,
                                    const std::uint8_t* data, std::size_t size) {
  static const std::string directory = std::filesystem::temp_directory_path().string();
  const std::string path = directory + "/ltlo_fuzz_" + tag + "_" + std::to_string(::getpid()) + suffix;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace ltlo::fuzz

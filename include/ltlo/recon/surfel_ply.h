#pragma once
/// surfels.ply: binary little-endian PLY with one vertex per surfel and the properties
///   float x y z nx ny nz, uchar red green blue, float radius confidence
/// (world frame, metres; opens in MeshLab, CloudCompare and Open3D as an oriented point cloud).
#include <string>
#include <vector>

#include "ltlo/recon/surfel.h"

namespace ltlo::recon {

/// Throws InputError naming the file when it cannot be written.
void writeSurfelPly(const std::string& path, const std::vector<Surfel>& surfels);

/// Reads a file written by writeSurfelPly (the times and violation counts are not stored: zero).
/// Throws InputError naming the file and what is wrong (header, property list, truncation).
std::vector<Surfel> readSurfelPly(const std::string& path);

}  // namespace ltlo::recon

// pbrt-v4's "nanovdb" medium: a density grid (and optionally a temperature
// grid) read from a NanoVDB (.nvdb) file through Debian's NanoVDB headers
// (libnanovdb-dev), resampled into the dense voxel grid every grid medium
// uses (scene/media.h).  Only this translation unit sees NanoVDB.
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

#include <string>

namespace theia {

// The largest dense grid a file may unfold to (1 GiB of floats).
inline constexpr uint64_t kMaxVdbVoxels = uint64_t(1) << 28;
// Voxels above these are clamped to them (with the NaN / negative warning): a
// density of 1e30 would make delta tracking take 1e30 null steps per unit.
inline constexpr float kMaxVdbDensity = 1e4f, kMaxVdbKelvin = 1e5f;

// Reads "filename" (relative to base_dir), "gridname" (default "density")
// and "temperaturename" (default "temperature", optional) into m's grid:
// nx, ny, nz, density, temperature, p0, p1 (in the file's world space, the
// medium's space).  Every problem with the file is one error at `loc` naming
// the file and what is wrong; NaN and negative voxels are clamped to 0, and
// voxels above kMaxVdbDensity / kMaxVdbKelvin to those, with one warning
// (simulation output often holds tiny negative densities).
void read_vdb_grids(const ParamList& params, const SourceLoc& loc, const std::string& base_dir, Medium& m);

}  // namespace theia

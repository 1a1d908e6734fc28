#include "scene/vdb_medium.h"

#include <iostream>  // GridValidator.h uses std::cerr without including it

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/IO.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace theia {

namespace {

namespace fs = std::filesystem;
using Handle = nanovdb::GridHandle<nanovdb::HostBuffer>;

// NanoVDB's reader trusts the sizes in the file (it allocates what a header
// claims and reads names up to a NUL), so the segment structure is checked
// against the file's size first.  Returns what is wrong, empty if nothing.
std::string check_structure(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const uint64_t size = fs::file_size(path);
  uint64_t pos = 0;
  while (pos < size) {
    nanovdb::io::Header header;
    if (size - pos < sizeof(header) || !in.read(reinterpret_cast<char*>(&header), sizeof(header)))
      return "truncated segment header";
    if (header.magic != NANOVDB_MAGIC_NUMBER) return "not a NanoVDB file (bad magic number)";
    pos += sizeof(header);
    if (header.codec != nanovdb::io::Codec::NONE && header.codec != nanovdb::io::Codec::ZIP)
      return fmt::format("grids compressed with codec {}, expected none or zip", int(header.codec));
    uint64_t data_bytes = 0;
    for (uint16_t g = 0; g < header.gridCount; ++g) {
      nanovdb::io::MetaData meta;
      if (size - pos < sizeof(meta) || !in.read(reinterpret_cast<char*>(&meta), sizeof(meta))) return "truncated grid metadata";
      pos += sizeof(meta);
      if (meta.nameSize < 1 || meta.nameSize > size - pos) return "a grid name runs past the end of the file";
      std::string name(meta.nameSize, '\0');
      in.read(name.data(), std::streamsize(name.size()));
      if (name.back() != '\0') return "a grid name is not terminated";
      pos += meta.nameSize;
      // Uncompressed grids are stored as they are; zip inflates by at most 1032.
      const uint64_t limit = header.codec == nanovdb::io::Codec::NONE ? meta.fileSize : meta.fileSize * 1032 + 64;
      if (meta.gridSize > limit || meta.fileSize > size) return "a grid claims more bytes than the file holds";
      if (meta.gridSize < sizeof(nanovdb::GridData)) return "a grid is smaller than its own header";
      data_bytes += meta.fileSize;
    }
    if (data_bytes > size - pos) return "truncated grid data";
    pos += data_bytes;
    in.seekg(std::streamoff(pos));
  }
  return "";
}

// A node of `size` bytes at `address` lies inside the buffer [begin, end)
// and is aligned as NanoVDB lays nodes out.
bool node_inside(uintptr_t address, size_t size, uintptr_t begin, uintptr_t end) {
  return address >= begin && address <= end && size <= end - address && address % NANOVDB_DATA_ALIGNMENT == 0;
}

// Every child the tree's masks lead to lies inside the grid's `bytes`, so the
// accessor that unfolds the grid cannot read past them.  NanoVDB's validator
// checks less than this when a file's checksum is partial (the default), and
// a flipped byte in a node then crashed the unfolding.
bool tree_inside(const nanovdb::FloatGrid& g, uint64_t bytes) {
  using Upper = nanovdb::NanoUpper<float>;
  using Lower = nanovdb::NanoLower<float>;
  const uintptr_t begin = reinterpret_cast<uintptr_t>(&g), end = begin + bytes;
  if (bytes < sizeof(nanovdb::GridData) + sizeof(nanovdb::NanoTree<float>)) return false;
  const auto* root = g.tree().root().data();
  const uintptr_t tiles = reinterpret_cast<uintptr_t>(root + 1);
  if (!node_inside(reinterpret_cast<uintptr_t>(root), sizeof(*root), begin, end) ||
      uint64_t(root->mTableSize) * sizeof(*root->tile(0)) > end - std::min(tiles, end))
    return false;
  for (uint32_t t = 0; t < root->mTableSize; ++t) {
    const auto* tile = root->tile(t);
    if (!tile->isChild()) continue;
    const uintptr_t upper_at = reinterpret_cast<uintptr_t>(root) + uintptr_t(tile->child);
    if (!node_inside(upper_at, sizeof(Upper), begin, end)) return false;
    const Upper* upper = reinterpret_cast<const Upper*>(upper_at);
    for (uint32_t i = 0; i < Upper::SIZE; ++i) {
      if (!upper->data()->mChildMask.isOn(i)) continue;
      const uintptr_t lower_at = upper_at + uintptr_t(upper->data()->mTable[i].child);
      if (!node_inside(lower_at, sizeof(Lower), begin, end)) return false;
      const Lower* lower = reinterpret_cast<const Lower*>(lower_at);
      for (uint32_t j = 0; j < Lower::SIZE; ++j)
        if (lower->data()->mChildMask.isOn(j) &&
            !node_inside(lower_at + uintptr_t(lower->data()->mTable[j].child), sizeof(nanovdb::NanoLeaf<float>), begin, end))
          return false;
    }
  }
  return true;
}

// The grid a handle holds, read in place: GridHandle::grid walks a chain of
// grid sizes that a corrupt header sends past the buffer.  check_structure
// made the buffer at least a grid header long; the type is checked by the caller.
const nanovdb::FloatGrid* float_grid(const Handle& handle) {
  return reinterpret_cast<const nanovdb::FloatGrid*>(handle.data());
}

// The named float grid, or an empty handle when the file has none of that
// name and it is optional.
Handle read_grid(const std::string& path, const std::string& name, bool required, const SourceLoc& loc) {
  Handle handle;
  try {
    handle = nanovdb::io::readGrid<nanovdb::HostBuffer>(path, name);
  } catch (const std::exception& e) {
    throw_at(loc, "nanovdb file \"{}\" could not be read: {}", path, e.what());
  }
  if (!handle) {
    if (required) throw_at(loc, "nanovdb file \"{}\" has no grid \"{}\", expected a float density grid of that name", path, name);
    return handle;
  }
  const nanovdb::FloatGrid* grid = float_grid(handle);
  if (grid->gridSize() > handle.size())
    throw_at(loc, "grid \"{}\" in \"{}\" is corrupt: it claims more bytes than were read", name, path);
  if (grid->gridType() != nanovdb::GridType::Float)
    throw_at(loc, "grid \"{}\" in \"{}\" does not hold floats, expected a float grid", name, path);
  // Nodes first: NanoVDB's own validator follows the tree's pointers unchecked.
  if (!tree_inside(*grid, grid->gridSize()))
    throw_at(loc, "grid \"{}\" in \"{}\" is corrupt: a node lies outside the grid", name, path);
  // Header, types and the checksum of the grid's head (its full checksum
  // walks node arrays whose counts are not checked).
  if (const std::string wrong = nanovdb::GridValidator<float>::check(*grid, false); !wrong.empty())
    throw_at(loc, "grid \"{}\" in \"{}\" is corrupt: {}", name, path, wrong);
  if (!grid->isFogVolume() && !grid->isUnknown())
    throw_at(loc, "grid \"{}\" in \"{}\" is not a fog volume, expected densities (pbrt-v4 reads fog volumes)", name, path);
  return handle;
}

// The index-to-world map must scale each axis by a positive factor (and
// translate): then the dense grid is a box of the medium's space.
void check_axis_aligned(const nanovdb::FloatGrid& g, const std::string& what, const SourceLoc& loc) {
  for (int a = 0; a < 3; ++a) {
    nanovdb::Vec3d axis(0.0);
    axis[a] = 1.0;
    const nanovdb::Vec3d w = g.indexToWorldDir(axis);
    for (int b = 0; b < 3; ++b)
      if (b == a ? !(w[b] > 0.0) : w[b] != 0.0)
        throw_at(loc, "{} has a rotated, sheared or mirrored voxel transform, expected an axis-aligned one", what);
  }
}

// Unfolds `grid` over the index box [lo, hi] (x fastest); NaN and negative
// voxels become 0 and voxels above `max` become `max`, counted in `clamped`.
std::vector<float> dense(const nanovdb::FloatGrid& grid, const nanovdb::Coord& lo, const nanovdb::Coord& hi, float max,
                         uint64_t& clamped) {
  std::vector<float> v;
  v.reserve(size_t(hi[0] - lo[0] + 1) * size_t(hi[1] - lo[1] + 1) * size_t(hi[2] - lo[2] + 1));
  auto acc = grid.getAccessor();
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y)
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const float d = acc.getValue(nanovdb::Coord(x, y, z));
        const float c = d >= 0.0f ? std::min(d, max) : 0.0f;  // NaN fails d >= 0
        clamped += c != d;
        v.push_back(c);
      }
  return v;
}

}  // namespace

void read_vdb_grids(const ParamList& params, const SourceLoc& loc, const std::string& base_dir, Medium& m) {
  const Param* f = params.find("filename", ParamType::String);
  if (!f) throw_at(loc, "nanovdb medium \"{}\" without \"string filename\", expected a NanoVDB (.nvdb) file", m.name);
  fs::path p(f->strings[0]);
  if (p.is_relative()) p = fs::path(base_dir) / p;
  const std::string path = p.lexically_normal().string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw_at(f->loc, "nanovdb file \"{}\" not found, expected an existing file", path);
  if (p.extension() == ".vdb")
    throw_at(f->loc, "\"{}\" is an OpenVDB file, expected NanoVDB (.nvdb): convert it with nanovdb_convert", path);
  if (const std::string wrong = check_structure(path); !wrong.empty())
    throw_at(f->loc, "nanovdb file \"{}\" is malformed: {}", path, wrong);
  const std::string density_name = params.get_string("gridname", "density");
  const Handle density = read_grid(path, density_name, true, f->loc);
  const Handle temperature = read_grid(path, params.get_string("temperaturename", "temperature"), false, f->loc);
  const nanovdb::FloatGrid& dg = *float_grid(density);
  check_axis_aligned(dg, fmt::format("grid \"{}\" in \"{}\"", density_name, path), f->loc);
  if (dg.activeVoxelCount() == 0) throw_at(f->loc, "grid \"{}\" in \"{}\" has no active voxels, expected a density", density_name, path);
  // One dense box over both grids' active voxels, which must share voxels.
  nanovdb::CoordBBox box = dg.indexBBox();
  const nanovdb::FloatGrid* tg = temperature ? float_grid(temperature) : nullptr;
  if (tg && tg->activeVoxelCount() > 0) {
    const nanovdb::Vec3d o = tg->indexToWorld(nanovdb::Vec3d(0.0)), e = tg->indexToWorld(nanovdb::Vec3d(1.0));
    if (o != dg.indexToWorld(nanovdb::Vec3d(0.0)) || e != dg.indexToWorld(nanovdb::Vec3d(1.0)))
      throw_at(f->loc, "the temperature and density grids in \"{}\" have different voxels, expected one voxel transform", path);
    box.expand(tg->indexBBox().min());
    box.expand(tg->indexBBox().max());
  }
  const nanovdb::Coord lo = box.min(), hi = box.max();
  if (!(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]))
    throw_at(f->loc, "grid \"{}\" in \"{}\" is corrupt: its index box is empty", density_name, path);
  m.nx = hi[0] - lo[0] + 1, m.ny = hi[1] - lo[1] + 1, m.nz = hi[2] - lo[2] + 1;
  if (uint64_t(m.nx) * uint64_t(m.ny) * uint64_t(m.nz) > kMaxVdbVoxels)
    throw_at(f->loc, "nanovdb file \"{}\" spans {} x {} x {} voxels, expected at most {} in all (theia unfolds the grid)", path,
             m.nx, m.ny, m.nz, kMaxVdbVoxels);
  uint64_t clamped = 0;
  m.density = dense(dg, lo, hi, kMaxVdbDensity, clamped);
  if (tg) m.temperature = dense(*tg, lo, hi, kMaxVdbKelvin, clamped);
  if (clamped > 0)
    warn_at(f->loc, "nanovdb file \"{}\": {} voxels NaN or negative (clamped to 0) or above {} density / {} K (clamped to it)",
            path, clamped, kMaxVdbDensity, kMaxVdbKelvin);
  // Voxel values sit at integer index coordinates (NanoVDB's trilinear
  // sampler); the dense grid's voxel centres are half a voxel in from its box.
  const nanovdb::Vec3d w0 = dg.indexToWorld(nanovdb::Vec3d(lo[0] - 0.5, lo[1] - 0.5, lo[2] - 0.5));
  const nanovdb::Vec3d w1 = dg.indexToWorld(nanovdb::Vec3d(hi[0] + 0.5, hi[1] + 0.5, hi[2] + 0.5));
  m.p0 = vec3(float(w0[0]), float(w0[1]), float(w0[2]));
  m.p1 = vec3(float(w1[0]), float(w1[1]), float(w1[2]));
}

}  // namespace theia

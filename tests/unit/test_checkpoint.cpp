// Checkpoint files: round trip, generations kept, corruption detected.
#include "checkpoint/checkpoint.h"
#include "checkpoint/fingerprint.h"
#include "core/log.h"
#include "scene/parser.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace theia;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / ("theia_ckpt_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  return d;
}

Checkpoint sample_checkpoint(uint64_t generation) {
  Checkpoint c;
  c.generation = generation;
  c.scene_hash = 0x1234;
  c.options_hash = 0x5678;
  c.image = ImageBuffer(3, 2, {"R", "G", "B", "A", "total.weight"});
  for (size_t i = 0; i < c.image.data.size(); ++i) c.image.data[i] = float(i) * 0.1f + float(generation);
  ByteWriter w;
  w.put<int32_t>(int32_t(generation));
  w.put_vector(std::vector<double>{1.5, 2.5});
  w.put_string("hello");
  c.sections.push_back({"scheduler", 1, w.bytes});
  c.sections.push_back({"guiding", 3, {1, 2, 3}});
  return c;
}

void flip_byte(const fs::path& p, size_t offset_from_end) {
  std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(-std::streamoff(offset_from_end), std::ios::end);
  char ch;
  f.get(ch);
  f.seekp(-std::streamoff(offset_from_end), std::ios::end);
  f.put(char(ch ^ 0x5a));
}

}  // namespace

TEST(Checkpoint, RoundTripsImageSectionsAndFingerprints) {
  fs::path d = fresh_dir("roundtrip");
  write_checkpoint(d.string(), sample_checkpoint(1));
  auto c = read_latest_checkpoint(d.string());
  ASSERT_TRUE(c);
  Checkpoint ref = sample_checkpoint(1);
  EXPECT_EQ(c->generation, 1u);
  EXPECT_EQ(c->scene_hash, ref.scene_hash);
  EXPECT_EQ(c->options_hash, ref.options_hash);
  ASSERT_EQ(c->image.width, 3);
  for (const std::string& ch : ref.image.channels) {
    int a = c->image.channel_index(ch), b = ref.image.channel_index(ch);
    ASSERT_GE(a, 0) << ch;
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 3; ++x) EXPECT_EQ(c->image.at(x, y, a), ref.image.at(x, y, b));
  }
  const CheckpointSection* s = c->find("scheduler");
  ASSERT_TRUE(s);
  ByteReader r(s->bytes, "test");
  EXPECT_EQ(r.get<int32_t>(), 1);
  EXPECT_EQ(r.get_vector<double>(), (std::vector<double>{1.5, 2.5}));
  EXPECT_EQ(r.get_string(), "hello");
  EXPECT_THROW(r.get<uint8_t>(), Error);  // past the end
  ASSERT_TRUE(c->find("guiding"));
  EXPECT_EQ(c->find("guiding")->version, 3u);
  EXPECT_FALSE(c->find("nothing"));
  fs::remove_all(d);
}

TEST(Checkpoint, KeepsThePreviousGenerationAndDropsOlderOnes) {
  fs::path d = fresh_dir("generations");
  for (uint64_t g = 1; g <= 4; ++g) write_checkpoint(d.string(), sample_checkpoint(g));
  EXPECT_FALSE(fs::exists(checkpoint_bin_path(d.string(), 2)));
  EXPECT_TRUE(fs::exists(checkpoint_bin_path(d.string(), 3)));
  EXPECT_TRUE(fs::exists(checkpoint_exr_path(d.string(), 3)));
  EXPECT_TRUE(fs::exists(checkpoint_bin_path(d.string(), 4)));
  for (const auto& e : fs::directory_iterator(d)) EXPECT_EQ(e.path().extension() == ".tmp", false);
  EXPECT_EQ(read_latest_checkpoint(d.string())->generation, 4u);
  fs::remove_all(d);
}

TEST(Checkpoint, TruncatedOrCorruptNewestFallsBackToThePreviousOne) {
  fs::path d = fresh_dir("corrupt");
  write_checkpoint(d.string(), sample_checkpoint(1));
  write_checkpoint(d.string(), sample_checkpoint(2));
  // Truncated .bin.
  fs::resize_file(checkpoint_bin_path(d.string(), 2), fs::file_size(checkpoint_bin_path(d.string(), 2)) - 5);
  std::vector<std::string> rejected;
  auto c = read_latest_checkpoint(d.string(), &rejected);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->generation, 1u);
  ASSERT_EQ(rejected.size(), 1u);
  EXPECT_NE(rejected[0].find("checkpoint-000002.bin"), std::string::npos) << rejected[0];

  // A flipped byte in the newest EXR.
  write_checkpoint(d.string(), sample_checkpoint(2));
  flip_byte(checkpoint_exr_path(d.string(), 2), 100);
  c = read_latest_checkpoint(d.string(), &rejected);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->generation, 1u);
  EXPECT_NE(rejected[0].find("checkpoint-000002.exr"), std::string::npos) << rejected[0];

  // A flipped byte inside the .bin (a section), and a missing EXR: nothing valid is left.
  flip_byte(checkpoint_bin_path(d.string(), 2), 20);
  fs::remove(checkpoint_exr_path(d.string(), 1));
  try {
    read_latest_checkpoint(d.string());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    std::string what = e.what();
    EXPECT_NE(what.find("no valid checkpoint"), std::string::npos) << what;
    EXPECT_NE(what.find("checksum"), std::string::npos) << what;
  }
  fs::remove_all(d);
}

TEST(Checkpoint, AnEmptyOrMissingDirectoryHoldsNone) {
  fs::path d = fresh_dir("empty");
  EXPECT_FALSE(read_latest_checkpoint(d.string()));
  fs::create_directories(d);
  std::ofstream(d / "checkpoint-000007.exr") << "orphan without its .bin";
  EXPECT_FALSE(read_latest_checkpoint(d.string()));
  fs::remove_all(d);
}

// Resume is refused when the scene changed: the fingerprint must see every
// parsed parameter that changes the image, including ones that live in an
// Include'd file (the main file's text alone would miss those).
TEST(SceneFingerprint, ChangesWithEveryImageAffectingParameter) {
  auto fp = [](const std::string& world) {
    return scene_fingerprint(parse_scene_string("WorldBegin\n" + world, "<fp>"));
  };
  const std::string base = R"(
    LightSource "spot" "point3 from" [0 2 0] "point3 to" [0 0 0]
    Material "dielectric" "float eta" 1.5 "float roughness" 0.1
    Shape "sphere"
  )";
  const uint64_t a = fp(base);
  EXPECT_EQ(a, fp(base));
  EXPECT_NE(a, fp(R"(LightSource "spot" "point3 from" [0 2 0] "point3 to" [1 0 0]
    Material "dielectric" "float eta" 1.5 "float roughness" 0.1
    Shape "sphere")"));
  EXPECT_NE(a, fp(R"(LightSource "spot" "point3 from" [0 2 0] "point3 to" [0 0 0]
    Material "dielectric" "float eta" 1.33 "float roughness" 0.1
    Shape "sphere")"));
  EXPECT_NE(a, fp(R"(LightSource "spot" "point3 from" [0 2 0] "point3 to" [0 0 0]
    Material "dielectric" "float eta" 1.5 "float roughness" 0.1
    Shape "sphere" "bool holdout" true)"));
  // Area-light fields that only the LightSet reads: "power" on a mesh of
  // unequal triangles (the per-triangle factors) and an image's normalisation.
  Scene emitter = parse_scene_string(R"(WorldBegin
    AreaLightSource "diffuse" "float power" 10
    Shape "trianglemesh" "point3 P" [0 0 0 2 0 0 2 1 0 2.5 0 0 3 0 0 3 1 0] "integer indices" [0 1 2 3 4 5])",
                                     "<fp>");
  ASSERT_EQ(emitter.lights.at(0).triangle_scale.size(), 2u);
  const uint64_t e = scene_fingerprint(emitter);
  emitter.lights[0].triangle_scale[1] *= 2.0f;
  EXPECT_NE(e, scene_fingerprint(emitter));
  emitter.lights[0].triangle_scale[1] /= 2.0f;
  EXPECT_EQ(e, scene_fingerprint(emitter));
  emitter.lights[0].power = 20.0f;
  EXPECT_NE(e, scene_fingerprint(emitter));
}

// Which zstd level each chunk is stored at (lib/package/write_package.cpp): the source map at level 3
// when levels 1 and 2 are asked for (there level 3 is faster and smaller), every other level as asked.
#include <gtest/gtest.h>

#include <filesystem>

#include "cluster/cluster.h"
#include "formats/chunk.h"
#include "gltf_builder.h"
#include "mesh/prepare.h"
#include "package/writer.h"
#include "package/write_package.h"
#include "reader/reader.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

// The stored size of `kind` in a package of FlightHelmet at `level`, and that chunk compressed again at
// `expect_level` (zstd is deterministic for a level and its parameters: the same bytes).
TEST(PackageLevels, SourceMapAtLevelThreeUnderLevelsOneAndTwo) {
  Scene scene = import_gltf((source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf").string());
  prepare_scene(scene, {});
  const Plan plan = plan_batching_points(scene, {});
  const fs::path dir = temp_dir("package_levels");
  struct Case {
    int asked, source_map, metadata;
  };
  for (const Case& c : {Case{1, 3, 1}, Case{2, 3, 2}, Case{5, 5, 5}, Case{-1, -1, -1}}) {
    ConvertOptions cv;
    cv.zstd_level = c.asked;
    const fs::path path = dir / ("level" + std::to_string(c.asked) + ".rtp");
    write_package(scene, plan, path.string(), cv);
    const PackageReader reader(path.string());
    for (const auto& [kind, expect] :
         {std::pair{fmt::ChunkKind::kSourceMap, c.source_map}, std::pair{fmt::ChunkKind::kMetadata, c.metadata}}) {
      const int64_t i = reader.find(kind, 0);
      ASSERT_GE(i, 0);
      const fmt::TocEntry& e = reader.toc()[size_t(i)];
      const AlignedBytes raw = reader.read(size_t(i));
      fmt::Compression comp;
      const AlignedBytes again = PackageWriter::compress(raw.data(), raw.size(), expect, comp);
      EXPECT_EQ(e.stored_size, again.size())
          << chunk_kind_name(uint32_t(kind)) << " asked level " << c.asked << ": not stored at level " << expect;
    }
  }
  // The point of it: under the default level the source map is the smaller for it.
  ConvertOptions def;
  const fs::path path = dir / "default.rtp";
  write_package(scene, plan, path.string(), def);
  const PackageReader reader(path.string());
  const size_t i = size_t(reader.find(fmt::ChunkKind::kSourceMap, 0));
  const AlignedBytes raw = reader.read(i);
  fmt::Compression comp;
  EXPECT_LT(2 * reader.toc()[i].stored_size, PackageWriter::compress(raw.data(), raw.size(), 1, comp).size());
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test

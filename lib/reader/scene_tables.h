#pragma once
// The instance table (kind 4) and mesh table (kind 5) a tracer holds so it can check every geometry
// chunk it decodes against them (formats/SPEC.md §4.6): read once, checked against each other.
#include <cstdint>
#include <string>

#include "layout/chunk_io.h"
#include "reader/check_chunks.h"
#include "reader/reader.h"

namespace rtp {

struct ResidentTables {
  AlignedBytes instance_bytes, mesh_bytes;
  SceneTables view;         // into the bytes
  uint64_t n_segments = 0;  // mesh-segment chunks in the TOC
  std::string instance_label, mesh_label;
  uint64_t bytes() const { return instance_bytes.size() + mesh_bytes.size(); }
};

// Reads both tables (CRC-checked, sections parsed); check_resident_tables is what makes them usable.
ResidentTables read_resident_tables(const PackageReader& r);
// check_mesh_table without the source map, check_instance_table against `points` batching points; throws
// Error(kInputInvalid) naming the chunk and the field.
void check_resident_tables(const ResidentTables& tables, uint64_t points);

}  // namespace rtp

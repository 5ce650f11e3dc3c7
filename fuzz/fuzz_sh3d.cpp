// dimr-fuzz-libs: dimr_data
// Fuzz target for the Sweet Home 3D catalogue reader: the input is read (1) as a .sh3f zip
// archive (every entry, the catalogue properties, every model), (2) as Java .properties text
// and (3) as the OBJ of a one-entry catalogue (wrapped in a valid stored zip, so the OBJ / MTL
// loader sees it). Everything must either work or throw dimr::Error; a returned model must be
// a valid mesh in the unit box.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "dimr/core/error.h"
#include "dimr/data/sh3d_catalog.h"
#include "dimr/geometry/crc32.h"

namespace {

void Put16(std::vector<std::uint8_t>* b, std::uint32_t v) {
  b->push_back(v & 0xFF);
  b->push_back((v >> 8) & 0xFF);
}
void Put32(std::vector<std::uint8_t>* b, std::uint32_t v) {
  Put16(b, v & 0xFFFF);
  Put16(b, v >> 16);
}
// A stored zip holding one entry `name` with `data`.
std::vector<std::uint8_t> OneEntryZip(const std::string& name, const std::uint8_t* data,
                                      std::size_t size) {
  std::vector<std::uint8_t> z;
  const std::uint32_t crc = dimr::geometry::Crc32(data, size);
  const std::uint32_t n = static_cast<std::uint32_t>(size);
  Put32(&z, 0x04034b50);
  Put16(&z, 20);
  Put16(&z, 0);
  Put16(&z, 0);
  Put32(&z, 0);
  Put32(&z, crc);
  Put32(&z, n);
  Put32(&z, n);
  Put16(&z, static_cast<std::uint32_t>(name.size()));
  Put16(&z, 0);
  z.insert(z.end(), name.begin(), name.end());
  z.insert(z.end(), data, data + size);
  const std::uint32_t cd = static_cast<std::uint32_t>(z.size());
  Put32(&z, 0x02014b50);
  Put16(&z, 20);
  Put16(&z, 20);
  Put16(&z, 0);
  Put16(&z, 0);
  Put32(&z, 0);
  Put32(&z, crc);
  Put32(&z, n);
  Put32(&z, n);
  Put16(&z, static_cast<std::uint32_t>(name.size()));
  for (int i = 0; i < 4; ++i) Put16(&z, 0);
  Put32(&z, 0);
  Put32(&z, 0);
  z.insert(z.end(), name.begin(), name.end());
  const std::uint32_t cd_size = static_cast<std::uint32_t>(z.size()) - cd;
  Put32(&z, 0x06054b50);
  Put32(&z, 0);
  Put16(&z, 1);
  Put16(&z, 1);
  Put32(&z, cd_size);
  Put32(&z, cd);
  Put16(&z, 0);
  return z;
}

void CheckModel(const dimr::data::CadModel& m) {
  m.mesh.Validate("fuzz sh3d model");
  for (const auto& v : m.mesh.vertices) {
    if (!(v.cwiseAbs().maxCoeff() <= 0.5 + 1e-9)) throw std::logic_error("vertex outside unit box");
  }
  if (m.mesh.vertex_colors.size() != m.mesh.vertices.size()) throw std::logic_error("colour count");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dimr::data;  // NOLINT(build/namespaces)
  // (1) As an archive.
  try {
    const ZipArchive z = ZipArchive::FromBytes(std::vector<std::uint8_t>(data, data + size), "f");
    for (const std::string& name : z.Names()) {
      try {
        const auto bytes = z.Read(name);
        if (name != "PluginFurnitureCatalog.properties") continue;
        const auto props =
            ParseJavaProperties(std::string(bytes.begin(), bytes.end()), "f:properties");
        for (const Sh3dEntry& e : ParseSh3dCatalog(props, "f", "f:properties")) {
          try {
            CheckModel(LoadSh3dModel(z, e, ClassifySh3dEntry(e.name, e.category)));
          } catch (const dimr::Error&) {
          }
        }
      } catch (const dimr::Error&) {
      }
    }
  } catch (const dimr::Error&) {
  }
  // (2) As properties text.
  try {
    const auto props =
        ParseJavaProperties(std::string(reinterpret_cast<const char*>(data), size), "p");
    (void)ParseSh3dCatalog(props, "p", "p");
  } catch (const dimr::Error&) {
  }
  // (3) As the OBJ of a catalogue entry.
  try {
    const ZipArchive z = ZipArchive::FromBytes(OneEntryZip("m/x.obj", data, size), "o");
    Sh3dEntry e;
    e.model_path = "/m/x.obj";
    e.width_cm = 50;
    e.depth_cm = 40;
    e.height_cm = 90;
    CheckModel(LoadSh3dModel(z, e, ClassifySh3dEntry("Chair", "Office")));
  } catch (const dimr::Error&) {
  }
  return 0;
}

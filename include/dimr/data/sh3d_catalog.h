// Real furniture from Sweet Home 3D furniture catalogues (Debian's `sweethome3d-furniture`:
// /usr/share/sweethome3d/furniture/*.sh3f, CC-BY 3.0 / CC0 OBJ models) imported into the
// canonical CAD frame of the procedural library (cad_library.h).
//
// A .sh3f file is a zip archive holding PluginFurnitureCatalog.properties (Java .properties:
// id#N, name#N, category#N, width#N / depth#N / height#N in cm, model#N = path of an OBJ in
// the zip, optional modelRotation#N = a row-major 3x3 matrix, creator#N, ...) and the OBJ /
// MTL / texture files. The reader here is self-contained: a zip central-directory reader with
// zlib inflate, a .properties parser (\uXXXX escapes, line continuations), an OBJ + MTL
// reader (diffuse colours; PNG / JPEG texture colours sampled at the UVs where libpng /
// libjpeg are available, MTL Kd otherwise).
//
// Frame: Sweet Home 3D models are y up with their front facing +z (towards the viewer) after
// modelRotation; width is along x, height along y, depth along z. Our canonical frame is
// x = forward, y = left, z = up, so (x, y, z)_canonical = (z, x, y)_sh3d (a cyclic
// permutation, det +1: face orientation is kept); nominal_size = (depth, width, height) / 100.
// The mesh is then normalised per axis to [-0.5, 0.5]^3 exactly like GenerateCadModel, so
// diag(nominal_size) * p has the catalogue's extents.
//
// docs/cad_library.md ("Real furniture") has the class map table, the held-out rule and the
// watertightness treatment.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/geometry/types.h"
#include "dimr/geometry/voxelize.h"

namespace dimr::data {

// ---------------------------------------------------------------------------------------
// Zip archives (stored and deflated entries; no encryption, no zip64 beyond 4 GiB).
// ---------------------------------------------------------------------------------------
class ZipArchive {
 public:
  // Reads the whole file and its central directory. Throws dimr::ParseError naming the file
  // for a missing / unreadable file or a malformed directory.
  static ZipArchive Open(const std::string& path);
  // An archive held in memory (`source` names it in errors).
  static ZipArchive FromBytes(std::vector<std::uint8_t> bytes, const std::string& source);

  const std::string& source() const { return source_; }
  // Entry names in directory order.
  std::vector<std::string> Names() const;
  bool Contains(const std::string& name) const;
  // Uncompressed bytes of an entry (names are matched exactly, then case-insensitively, a
  // leading '/' is ignored). Throws dimr::ParseError naming the file and the entry for a
  // missing entry, an unsupported method, a corrupt stream or a CRC-32 mismatch.
  std::vector<std::uint8_t> Read(const std::string& name) const;

 private:
  struct Entry {
    std::string name;
    std::uint16_t method = 0;
    std::uint32_t crc = 0;
    std::uint64_t compressed = 0, uncompressed = 0, local_offset = 0;
  };
  const Entry* Find(const std::string& name) const;
  std::string source_;
  std::shared_ptr<const std::vector<std::uint8_t>> bytes_;
  std::vector<Entry> entries_;
  std::map<std::string, std::size_t> by_name_;
};

// Java .properties text (ISO 8859-1 bytes with \uXXXX escapes; output UTF-8): `key=value`,
// `key:value` or `key value`; `#` / `!` comments; a line ending in an odd number of
// backslashes continues on the next (leading blanks of the continuation dropped); escapes
// \t \n \r \f \\ \uXXXX (surrogate pairs joined) and \<other> = <other>. Later keys replace
// earlier ones. Throws dimr::ParseError naming `source` and the line for a bad \u escape.
std::map<std::string, std::string> ParseJavaProperties(const std::string& text,
                                                       const std::string& source);

// ---------------------------------------------------------------------------------------
// Catalogue entries and the class map.
// ---------------------------------------------------------------------------------------
struct Sh3dEntry {
  std::string catalog;  // catalogue file stem, e.g. "BlendSwap-CC-BY"
  int index = 0;        // N of the #N keys
  std::string id, name, category, tags, creator, model_path;
  std::string license;  // the entry's licence or, failing that, the catalogue's
  std::string catalog_name, catalog_provider;
  double width_cm = 0, depth_cm = 0, height_cm = 0;
  bool door_or_window = false;
  bool has_rotation = false;
  Eigen::Matrix3d model_rotation = Eigen::Matrix3d::Identity();  // row-major in the file
};

// Parses a catalogue's properties into entries (in index order). Entries without model or
// size are skipped; a size that is not a positive finite number is a dimr::ParseError naming
// the source and key.
std::vector<Sh3dEntry> ParseSh3dCatalog(const std::map<std::string, std::string>& props,
                                        const std::string& catalog, const std::string& source);

// What an entry becomes: one of the 8 CAD classes, a distractor of our room composer (its
// GenerateDistractor kind, so rooms place it like the procedural one), another labelled
// object (toilet, sink, ...: imported but not placed), or nothing.
struct Sh3dClass {
  int cad_class = -1;        // 0..7 or -1
  int rfs_class = -1;        // 25-class label; -1 = ignore (clutter)
  int distractor_kind = -1;  // GenerateDistractor kind for non-CAD objects, -1 if none
  std::string label;         // short name of the rule ("chair", "bed", "kitchen_cabinet")
  bool Skip() const { return label.empty(); }
};
// The rule table of docs/cad_library.md applied to the (English) name and category.
Sh3dClass ClassifySh3dEntry(const std::string& name, const std::string& category);

// Held-out split: a fixed 20 % of the models, by FNV-1a of the model id (model id = first 32
// hex of two SplitMix64 finalisations of FNV-1a("dimr-sh3d" catalog "#" id)).
std::string Sh3dModelId(const Sh3dEntry& e);
bool IsHeldOutModel(const std::string& model_id);

// ---------------------------------------------------------------------------------------
// Models.
// ---------------------------------------------------------------------------------------
struct Sh3dLoadStats {
  int materials = 0, textures_sampled = 0, textures_missing = 0;
  std::size_t input_faces = 0;
  int boundary_edges = 0;  // after welding equal positions: edges with one face
};

// Loads the entry's OBJ from the archive into a canonical CadModel (cad_class / rfs_class /
// synset from `cls`; family "sh3d_<rule>", one part per OBJ group / material run, vertex
// colours = sRGB 8-bit diffuse colours). Vertices at equal positions are welded. Throws
// dimr::ParseError naming archive and entry for a missing / malformed OBJ or an empty model.
CadModel LoadSh3dModel(const ZipArchive& zip, const Sh3dEntry& e, const Sh3dClass& cls,
                       Sh3dLoadStats* stats = nullptr);

// Inside / outside for BSP training of a mesh that may have holes (real furniture is a soup of
// open surfaces): the surface voxels of a `res`^3 grid over [-0.5, 0.5]^3 (plus padding) are
// dilated by `close_cells`, the outside is flood-filled from the border through the empty
// cells, and the outside is dilated back by `close_cells` (a morphological closing of the
// complement): gaps narrower than about 2 * close_cells cells are closed, everything not
// reachable from outside is solid. Cells of the original surface stay solid.
geometry::VoxelGrid ClosedOccupancy(const geometry::TriangleMesh& unit_mesh, int res,
                                    int close_cells);
// A closed, outward-oriented mesh of the occupied cells (two triangles per boundary face
// between an occupied and an empty cell).
geometry::TriangleMesh OccupancyToMesh(const geometry::VoxelGrid& grid);

// ---------------------------------------------------------------------------------------
// Whole import.
// ---------------------------------------------------------------------------------------
struct ImportedModel {
  CadModel model;
  Sh3dEntry entry;
  Sh3dClass cls;
  bool held_out = false;
  Sh3dLoadStats stats;
  geometry::Vec3 mean_color = geometry::Vec3::Constant(0.6);  // area-weighted, linear [0,1]
  double solid_fraction_open = 0;    // VoxelizeFilled occupancy of the unit box (no repair)
  double solid_fraction_closed = 0;  // ClosedOccupancy
};

struct ImportOptions {
  bool include_distractors = true;  // also the non-CAD classified entries
  int watertight_res = 64;          // ClosedOccupancy grid (0: skip the check)
  int close_cells = 1;
};

// Imports every classified entry of the catalogues (sorted by catalogue and index).
// Throws dimr::ParseError for unreadable catalogues; a single model that fails to load is
// reported in `errors` (its message) and skipped.
std::vector<ImportedModel> ImportSh3dCatalogs(const std::vector<std::string>& paths,
                                              const ImportOptions& opt,
                                              std::vector<std::string>* errors = nullptr);

// Default catalogue directory of the Debian package.
std::string DefaultSh3dFurnitureDir();
// The *.sh3f files of a directory, sorted. Throws dimr::InvalidArgument if there are none.
std::vector<std::string> ListSh3dCatalogs(const std::string& dir);

}  // namespace dimr::data

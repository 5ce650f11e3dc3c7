// PipelineBackend (the node's production backend) with the shipped models: get_pool_model
// returns a pool entry's real CAD mesh from the ShapeNet-style tree given as pool_meshes, in
// the canonical frame, with a file:// resource; unknown ids and entries without a mesh are
// "not found"; retrieval is refused without pool meshes and accepted with them.
#include "dimr/ros/pipeline_backend.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "dimr/core/labels.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/pipeline/reconstructor_config.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::ros1 {
namespace {

namespace fs = std::filesystem;

pipeline::ReconstructorConfig ShippedModels() {
  const std::string root = DIMR_SOURCE_DIR;
  pipeline::ReconstructorConfig c;
  c.stage1_model = root + "/models/stage1/stage1.pt";
  c.stage2_model = root + "/models/stage2/stage2.pt";
  c.bsp_model = root + "/models/bsp/bsp.pt";
  c.pool = root + "/models/bsp/pool.bin";
  return c;
}

TEST(PipelineBackend, PoolModelReturnsTheRealCadMeshOfAPoolEntry) {
  pipeline::ReconstructorConfig c = ShippedModels();
  const pipeline::ShapePool pool = pipeline::ShapePool::Load(c.pool);
  ASSERT_GT(pool.size(), 2u);
  const pipeline::PoolEntry& e = pool.entries()[1];
  // A tree holding that one model: a tetrahedron in ShapeNet axes (y up, -z forward).
  const fs::path tree = fs::temp_directory_path() / ("dimr_pool_tree_" + std::to_string(getpid()));
  fs::remove_all(tree);
  const fs::path obj =
      tree / data::ShapeNetRelativePath(labels::CadSynsets()[static_cast<std::size_t>(e.cad_class)],
                                        e.model_id);
  fs::create_directories(obj.parent_path());
  geometry::TriangleMesh tet;
  tet.vertices = {{0.1, 0.2, 0.3}, {0.4, 0.0, 0.0}, {0.0, 0.4, 0.0}, {0.0, 0.0, -0.4}};
  tet.faces = {{0, 1, 2}, {0, 2, 3}, {0, 3, 1}, {1, 3, 2}};
  geometry::WriteObj(obj.string(), tet);

  {
    // Without pool meshes: no mesh to return, retrieval refused with a reason.
    PipelineBackend backend(c);
    geometry::TriangleMesh mesh;
    std::string resource, why;
    EXPECT_TRUE(backend.has_pool());
    EXPECT_FALSE(backend.PoolModel(e.model_id, &mesh, &resource));
    EXPECT_FALSE(backend.SupportsMode(ShapeMode::kRetrieval, &why));
    EXPECT_FALSE(why.empty());
  }
  c.pool_meshes = tree.string();
  PipelineBackend backend(c);
  std::string why;
  EXPECT_TRUE(backend.SupportsMode(ShapeMode::kRetrieval, &why)) << why;
  geometry::TriangleMesh mesh;
  std::string resource;
  ASSERT_TRUE(backend.PoolModel(e.model_id, &mesh, &resource));
  ASSERT_EQ(mesh.faces.size(), 4u);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  // ShapeNet (x, y, z) -> canonical (-z, -x, y).
  EXPECT_NEAR(mesh.vertices[0].x(), -0.3, 1e-6);
  EXPECT_NEAR(mesh.vertices[0].y(), -0.1, 1e-6);
  EXPECT_NEAR(mesh.vertices[0].z(), 0.2, 1e-6);
  EXPECT_EQ(resource, "file://" + fs::absolute(obj).string());
  // Another entry (no file in the tree) and an unknown id: not found.
  EXPECT_FALSE(backend.PoolModel(pool.entries()[2].model_id, &mesh, &resource));
  EXPECT_FALSE(backend.PoolModel("no-such-model", &mesh, &resource));
  fs::remove_all(tree);
}

}  // namespace
}  // namespace dimr::ros1

// Instance re-labelling of a real ScanNet scene with its Scan2CAD annotation, as the DIMR
// reference builds its training data (generate_data_relabel.py; spec:
// ../shared/reference/dimr-method.md section 8.3).
//
// Frames. ReadScanNetScene returns the raw mesh vertices and the scene's `axisAlignment`
// matrix A without applying it. Scan2CAD model `trs` live in Scan2CAD's world frame, in which
// the scan sits at the scene-level `trs` M_scan; the reference maps a model to the axis-aligned
// scan with  A * inv(M_scan) * M_cad.  RelabelWithScan2Cad therefore first axis-aligns the
// scene (AxisAlignScene: points p <- A p, matrix reset to the identity) and maps every model
// with the same A * inv(M_scan), so points and boxes share the axis-aligned frame, z up.
//
// Semantic labels. Vertices in no aggregation segment are already kSemanticIgnore from
// ReadScanNetScene (the reference keeps them as 0 = wall, a bug we do not copy); the
// re-labelling never changes a per-point semantic label.
#pragma once

#include <Eigen/Core>
#include <string>

#include "dimr/data/scan2cad_io.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/oriented_box.h"

namespace dimr::data {

struct RelabelStats {
  int kept = 0;             // ScanNet instances kept (every class but ignore / 2, 5, 7)
  int dropped_ignored = 0;  // instances of an ignored class (rfs -1 / 255): points -> instance 0
  int dropped_rebuilt = 0;  // bookshelf / cabinet / bathtub instances dropped for rebuilding
  int rebuilt = 0;          // new instances from Scan2CAD bookshelf / cabinet / bathtub boxes
  int rebuilt_empty = 0;    // such boxes without a single unassigned point inside (no instance)
  int linked = 0;           // models of the other CAD classes linked to a kept instance
  int unmatched = 0;        // models of the other CAD classes with IoU 0 against every instance
  int non_cad_models = 0;   // models whose synset is none of the 8 CAD classes (skipped)
  int kept_with_box = 0;    // kept instances that ended with a Scan2CAD box (cad_class >= 0)
  int points_lost = 0;      // points of dropped instances that no rebuilt instance claimed
};

// The 4x4 map from Scan2CAD world coordinates to the scene's axis-aligned frame:
// axis_alignment * inv(M_scan), M_scan = T * R * S of the annotation's scene `trs`. Throws
// dimr::InvalidArgument naming the scan when M_scan is singular.
Eigen::Matrix4d Scan2CadToAlignedScene(const Eigen::Matrix4d& axis_alignment,
                                       const Scan2CadScene& annotation);

// The reference's 7-DoF box of one Scan2CAD model, `to_scene` applied after the model's trs:
// centre = image of `center`; the ShapeNet axes forward (-z), left (-x), up (+y) are mapped,
// the one with the largest z component becomes "up" (the others keep their order, forward
// first, as the reference rectifies lying models); heading = atan2 of forward projected to the
// floor, in (-pi, pi]; size = 2 |bbox| times the axis stretch, ordered (forward, left, up).
// Throws dimr::InvalidArgument naming the model (id_cad) for a degenerate transform.
geometry::OrientedBox Scan2CadModelBox(
    const Scan2CadModel& model, const Eigen::Matrix4d& to_scene = Eigen::Matrix4d::Identity());

// Applies scene->axis_alignment to the points and to every instance's box and alignment
// (rigidly; heading += the matrix's yaw), rounds points to float, and resets the matrix to the
// identity (a second call is a no-op). Throws dimr::InvalidArgument naming the scene when the
// matrix is not a rotation about z (tolerance 1e-3) plus a translation.
void AxisAlignScene(SynthScene* scene);

// Re-labels `scene` (as read by ReadScanNetScene, any frame) in place, dimr-method.md 8.3:
//  1. AxisAlignScene; every kept instance's box = axis-aligned box of its points (heading 0).
//  2. Instances with rfs_class < 0 (ignored) are dropped; instances whose CAD class
//     (RfsToCad(rfs_class)) is bookshelf, cabinet or bathtub are dropped for rebuilding;
//     their points get instance 0. All other instances are kept, stuff included.
//  3. Models in annotation order (class = CadClassFromSynset(catid_cad); others skipped):
//     - bookshelf / cabinet / bathtub: every point with instance 0 inside the model box
//       expanded by 5 cm per side becomes a new instance (id = largest id + 1, ...): category
//       = CAD class name, rfs_class = the majority per-point label when RfsToCad of it is the
//       model's class, else CadToRfs(class); per-point labels are kept. No point, no instance.
//     - other classes: linked to the kept ScanNet instance with the largest BoxIoU(model box,
//       instance box), no class check, first on ties; IoU 0 -> unmatched. A later model
//       linked to the same instance overwrites the earlier one (the reference loader keeps
//       the last).
//     A linked / rebuilt instance gets cad_class, box, synset, model_id, symmetric (sym !=
//     "__SYM_NONE") and its trs mapped into the scene frame (rotation from the closest
//     rotation of the scene map, scale times its cube-root determinant).
//  4. Kept instances no model was linked to get cad_class = -1 (the reference takes an
//     instance's CAD class and heading only from a Scan2CAD box); num_points is recounted.
// Rebuilt instances may hold points of other labels (as in the reference), so the result
// need not satisfy SynthScene::Validate's label consistency. Throws dimr::InvalidArgument
// naming the scene when the annotation's id_scan differs from scene->name or per-point arrays
// disagree in length, and as the functions above.
RelabelStats RelabelWithScan2Cad(SynthScene* scene, const Scan2CadScene& annotation);

// "kept 12, dropped 3 ignored + 4 rebuilt, rebuilt 5 (1 empty), linked 7, unmatched 1, ..."
std::string ToString(const RelabelStats& stats);

}  // namespace dimr::data

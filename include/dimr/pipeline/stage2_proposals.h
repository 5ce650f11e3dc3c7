// Stage-2 proposals (dimr-method.md section 4): canonicalisation of a stage-1 proposal
// (heading, centre, extents, the per-proposal 20^3 grid), matching proposals to GT instances
// with the soft score targets, and the test-time box decode. LibTorch-free.
//
// Frames: the canonical frame of a proposal with heading theta and centre c0 is
//   u = Rz(-theta) (p - c0),   p = Rz(theta) u + c0,
// with c0 the centre of the bounding box of the points in the heading-aligned frame (so the
// canonical points span [-s0/2, s0/2]); x = the object's forward axis, y = left, z = up, the
// frame of geometry::OrientedBox and of the BSP decoder's [-1, 1]^3 (x forward, y left, z up).
// The reference uses the world axis-aligned box centre instead (docs/stage2.md).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "dimr/geometry/oriented_box.h"
#include "dimr/nn/stage2_data.h"

namespace dimr::pipeline {

struct ProposalFrame {
  double heading = 0;                                                // theta, radians
  Eigen::Vector3d center = Eigen::Vector3d::Zero();                  // c0 (input frame)
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();                  // s0 (canonical extents)
  Eigen::Vector3d ToLocal(const Eigen::Vector3d& p) const;           // Rz(-theta) (p - c0)
  Eigen::Vector3d ToWorld(const Eigen::Vector3d& u) const;           // Rz(theta) u + c0
  Eigen::Vector3d DirectionToLocal(const Eigen::Vector3d& v) const;  // Rz(-theta) v
  Eigen::Vector3d DirectionToWorld(const Eigen::Vector3d& v) const;  // Rz(theta) v
};

// The frame of the points `indices` of `points` under `heading`. Throws dimr::InvalidArgument
// for an empty index list, an index out of range, a non-finite point or heading.
ProposalFrame ComputeProposalFrame(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<int>& indices, double heading);

// One proposal as a stage-2 sample (no targets): canonical points, the stage-1 features of its
// points (features: N_scene x feature_dim row-major), extents, centre height above `floor_z`.
// `frame` receives the frame. Degenerate proposals (all points identical) get a tiny extent
// (the voxel scale is bounded), never a division by zero.
nn::Stage2Sample CanonicaliseProposal(const std::vector<Eigen::Vector3f>& points,
                                      const std::vector<float>& features, int feature_dim,
                                      float floor_z, const std::vector<int>& indices, int cad_class,
                                      double heading, ProposalFrame* frame);

// Test-time box (section 4.5): centre = c0 + Rz(theta) dc, size = s0 + max(ds, -0.1 s0)
// element-wise (shrinking limited to 10 %), heading = theta.
geometry::OrientedBox DecodeBox(const ProposalFrame& frame, const Eigen::Vector3f& center_residual,
                                const Eigen::Vector3f& size_residual);
// The box of the proposal itself (zero residuals): centre c0, size s0, heading theta.
geometry::OrientedBox ProposalBox(const ProposalFrame& frame);

// ---------------------------------------------------------------- matching (section 4.3)
struct ProposalMatch {
  double iou = 0;  // max over GT instances of |P n G| / (|P| + |G| - |P n G| + 1e-5)
  int gt = -1;     // argmax instance (index into the scene's instances), -1 if no overlap
};
// gt_instance: per scene point the GT instance index or -1; num_instances: their count.
// Every instance counts (CAD or not). Throws dimr::InvalidArgument for an index out of range.
std::vector<ProposalMatch> MatchProposals(const std::vector<std::vector<int>>& proposals,
                                          const std::vector<int>& gt_instance, int num_instances);

// Fills the training targets of `sample` from its match: iou, and when the GT instance has a
// CAD class and a code: gt_class, the centre target Rz(-theta) (c_gt - c0), the GT size and
// the code.
void SetStage2Targets(const ProposalFrame& frame, const ProposalMatch& match, int gt_cad_class,
                      const geometry::OrientedBox* gt_box, const Eigen::VectorXf* gt_code,
                      nn::Stage2Sample* sample);

}  // namespace dimr::pipeline

// Stage-2 canonicalisation, matching and box decode (include/dimr/pipeline/stage2_proposals.h).
#include "dimr/pipeline/stage2_proposals.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {

namespace {

Eigen::Vector3d RotZ(const Eigen::Vector3d& v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return Eigen::Vector3d(c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z());
}

}  // namespace

Eigen::Vector3d ProposalFrame::ToLocal(const Eigen::Vector3d& p) const {
  return RotZ(p - center, -heading);
}
Eigen::Vector3d ProposalFrame::ToWorld(const Eigen::Vector3d& u) const {
  return RotZ(u, heading) + center;
}
Eigen::Vector3d ProposalFrame::DirectionToLocal(const Eigen::Vector3d& v) const {
  return RotZ(v, -heading);
}
Eigen::Vector3d ProposalFrame::DirectionToWorld(const Eigen::Vector3d& v) const {
  return RotZ(v, heading);
}

ProposalFrame ComputeProposalFrame(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<int>& indices, double heading) {
  if (indices.empty()) throw InvalidArgument("stage2 proposal: no points");
  if (!std::isfinite(heading)) throw InvalidArgument("stage2 proposal: heading is not finite");
  ProposalFrame f;
  f.heading = heading;
  const double c = std::cos(heading), s = std::sin(heading);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int i : indices) {
    if (i < 0 || static_cast<std::size_t>(i) >= points.size()) {
      throw InvalidArgument("stage2 proposal: point index " + std::to_string(i) +
                            " outside the cloud of " + std::to_string(points.size()) + " points");
    }
    const Eigen::Vector3d p = points[i].cast<double>();
    if (!p.allFinite()) {
      throw InvalidArgument("stage2 proposal: point " + std::to_string(i) + " is not finite");
    }
    // Rz(-theta) p, about the origin: the box centre is rotated back below.
    const Eigen::Vector3d r(c * p.x() + s * p.y(), -s * p.x() + c * p.y(), p.z());
    lo = lo.cwiseMin(r);
    hi = hi.cwiseMax(r);
  }
  f.extent = hi - lo;
  f.center = RotZ(0.5 * (lo + hi), heading);
  return f;
}

nn::Stage2Sample CanonicaliseProposal(const std::vector<Eigen::Vector3f>& points,
                                      const std::vector<float>& features, int feature_dim,
                                      float floor_z, const std::vector<int>& indices, int cad_class,
                                      double heading, ProposalFrame* frame) {
  if (feature_dim < 0 || features.size() != points.size() * static_cast<std::size_t>(feature_dim)) {
    throw InvalidArgument("stage2 proposal: " + std::to_string(features.size()) +
                          " feature values for " + std::to_string(points.size()) + " points x " +
                          std::to_string(feature_dim));
  }
  if (cad_class < 0 || cad_class >= nn::kStage2CadClasses) {
    throw InvalidArgument("stage2 proposal: CAD class " + std::to_string(cad_class) +
                          " outside 0..7");
  }
  if (!std::isfinite(floor_z)) throw InvalidArgument("stage2 proposal: floor height not finite");
  const ProposalFrame f = ComputeProposalFrame(points, indices, heading);
  nn::Stage2Sample s;
  s.proposal_class = cad_class;
  s.feature_dim = feature_dim;
  s.local.reserve(indices.size());
  s.features.reserve(indices.size() * feature_dim);
  for (int i : indices) {
    s.local.push_back(f.ToLocal(points[i].cast<double>()).cast<float>());
    s.features.insert(s.features.end(),
                      features.begin() + static_cast<std::size_t>(i) * feature_dim,
                      features.begin() + static_cast<std::size_t>(i + 1) * feature_dim);
  }
  s.extent = f.extent.cast<float>();
  s.center_height = static_cast<float>(f.center.z() - floor_z);
  if (frame) *frame = f;
  return s;
}

geometry::OrientedBox DecodeBox(const ProposalFrame& frame, const Eigen::Vector3f& center_residual,
                                const Eigen::Vector3f& size_residual) {
  geometry::OrientedBox b;
  b.center = frame.ToWorld(center_residual.cast<double>());
  const Eigen::Vector3d ds = size_residual.cast<double>();
  b.size = frame.extent + ds.cwiseMax(-0.1 * frame.extent);
  b.heading = frame.heading;
  return b;
}

geometry::OrientedBox ProposalBox(const ProposalFrame& frame) {
  return DecodeBox(frame, Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero());
}

std::vector<ProposalMatch> MatchProposals(const std::vector<std::vector<int>>& proposals,
                                          const std::vector<int>& gt_instance, int num_instances) {
  std::vector<int> size(std::max(0, num_instances), 0);
  for (std::size_t i = 0; i < gt_instance.size(); ++i) {
    const int g = gt_instance[i];
    if (g < -1 || g >= num_instances) {
      throw InvalidArgument("MatchProposals: point " + std::to_string(i) + " has instance " +
                            std::to_string(g) + " outside [-1, " + std::to_string(num_instances) +
                            ")");
    }
    if (g >= 0) ++size[g];
  }
  std::vector<ProposalMatch> out(proposals.size());
  std::unordered_map<int, int> inter;
  for (std::size_t k = 0; k < proposals.size(); ++k) {
    inter.clear();
    for (int i : proposals[k]) {
      if (i < 0 || static_cast<std::size_t>(i) >= gt_instance.size()) {
        throw InvalidArgument("MatchProposals: proposal " + std::to_string(k) + " has point " +
                              std::to_string(i) + " outside the cloud");
      }
      if (gt_instance[i] >= 0) ++inter[gt_instance[i]];
    }
    const double np = static_cast<double>(proposals[k].size());
    for (const auto& [g, n] : inter) {
      const double iou = n / (np + size[g] - n + 1e-5);
      if (iou > out[k].iou || (iou == out[k].iou && g < out[k].gt)) {
        out[k].iou = iou;
        out[k].gt = g;
      }
    }
  }
  return out;
}

void SetStage2Targets(const ProposalFrame& frame, const ProposalMatch& match, int gt_cad_class,
                      const geometry::OrientedBox* gt_box, const Eigen::VectorXf* gt_code,
                      nn::Stage2Sample* sample) {
  sample->iou = static_cast<float>(std::clamp(match.iou, 0.0, 1.0));
  sample->gt_class = -1;
  sample->code.clear();
  sample->center_target.setZero();
  sample->size_target.setZero();
  sample->heading_target = 0;
  if (match.gt < 0 || gt_cad_class < 0 || gt_box == nullptr || gt_code == nullptr ||
      gt_code->size() == 0) {
    return;
  }
  if (gt_cad_class >= nn::kStage2CadClasses) {
    throw InvalidArgument("SetStage2Targets: CAD class " + std::to_string(gt_cad_class));
  }
  sample->gt_class = gt_cad_class;
  sample->center_target = frame.ToLocal(gt_box->center).cast<float>();
  sample->size_target = gt_box->size.cast<float>();
  sample->heading_target =
      static_cast<float>(std::remainder(gt_box->heading - frame.heading, 2 * M_PI));
  sample->code.assign(gt_code->data(), gt_code->data() + gt_code->size());
}

}  // namespace dimr::pipeline

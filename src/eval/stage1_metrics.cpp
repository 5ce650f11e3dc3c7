#include "dimr/eval/stage1_metrics.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::eval {

Stage1MetricsAccumulator::Stage1MetricsAccumulator(int num_semantic, int num_cad)
    : num_semantic_(num_semantic), num_cad_(num_cad) {
  if (num_semantic < 1 || num_cad < 1) {
    throw InvalidArgument("Stage1MetricsAccumulator: class counts must be >= 1");
  }
  gt_objects_.assign(num_semantic, 0);
  gt_scenes_.assign(num_semantic, 0);
}

void Stage1MetricsAccumulator::Add(const Stage1SceneEval& s) {
  const std::string who = "stage1 metrics: scene " + std::to_string(scenes_);
  const std::size_t n = s.gt_semantic.size();
  if (s.gt_instance.size() != n || s.pred_semantic.size() != n) {
    throw InvalidArgument(who + ": gt_semantic, gt_instance and pred_semantic differ in size");
  }
  const int num_inst = static_cast<int>(s.gt_instances.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (s.gt_instance[i] >= num_inst) {
      throw InvalidArgument(who + ": gt_instance[" + std::to_string(i) + "] out of range");
    }
  }
  InstanceScene is;
  is.gt_label.assign(n, -1);
  is.gt_instance.assign(n, -1);
  std::vector<int> inst_size(s.gt_instances.size(), 0);
  // Support: the scenes holding each class and each GT instance's majority class.
  const int nc = num_semantic_;
  std::vector<char> in_scene(nc, 0);
  std::vector<int> votes(s.gt_instances.size() * static_cast<std::size_t>(nc), 0);
  for (std::size_t i = 0; i < n; ++i) {
    const int k = s.gt_instance[i];
    const int g = s.gt_semantic[i];
    if (g >= 0 && g < nc) {
      in_scene[g] = 1;
      if (k >= 0) ++votes[static_cast<std::size_t>(k) * nc + g];
    }
    if (k < 0 || s.gt_instances[k].cad_class < 0) continue;
    is.gt_label[i] = s.gt_instances[k].cad_class;
    is.gt_instance[i] = k;
    ++inst_size[k];
  }
  for (int c = 0; c < nc; ++c) gt_scenes_[c] += in_scene[c];
  for (std::size_t k = 0; k < s.gt_instances.size(); ++k) {
    const auto first = votes.begin() + static_cast<std::ptrdiff_t>(k * nc);
    const auto best = std::max_element(first, first + nc);
    if (*best > 0) ++gt_objects_[best - first];
  }
  for (const auto& p : s.preds) {
    is.preds.push_back({p.cad_class, p.score, p.points});
    // Heading error against the GT instance holding most of its points (IoU > 0.5).
    std::vector<int> count(s.gt_instances.size(), 0);
    for (int i : p.points) {
      if (i < 0 || static_cast<std::size_t>(i) >= n) {
        throw InvalidArgument(who + ": a prediction's point index " + std::to_string(i) +
                              " is out of range");
      }
      if (s.gt_instance[i] >= 0) ++count[s.gt_instance[i]];
    }
    if (count.empty()) continue;
    const int best = static_cast<int>(std::max_element(count.begin(), count.end()) - count.begin());
    if (!s.gt_instances[best].has_heading) continue;
    const double iou = static_cast<double>(count[best]) /
                       (static_cast<double>(p.points.size()) + inst_size[best] - count[best]);
    if (iou <= 0.5) continue;
    const double d = std::remainder(p.heading - s.gt_instances[best].heading, 2 * M_PI);
    heading_errors_.push_back(std::abs(d) * 180.0 / M_PI);
  }
  inst_scenes_.push_back(std::move(is));
  gt_sem_.insert(gt_sem_.end(), s.gt_semantic.begin(), s.gt_semantic.end());
  pred_sem_.insert(pred_sem_.end(), s.pred_semantic.begin(), s.pred_semantic.end());
  ++scenes_;
}

double SupportedMiou(const Stage1Metrics& m, int min_objects, int* classes) {
  if (min_objects < 0) {
    throw InvalidArgument("SupportedMiou: min_objects must be >= 0, got " +
                          std::to_string(min_objects));
  }
  double sum = 0;
  int n = 0;
  const std::size_t nc = std::min(m.gt_objects.size(), m.semantic.iou.size());
  for (std::size_t c = 0; c < nc; ++c) {
    if (m.semantic.tp[c] + m.semantic.fn[c] == 0 || m.gt_objects[c] < min_objects) continue;
    sum += m.semantic.iou[c];
    ++n;
  }
  if (classes) *classes = n;
  return n ? sum / n : 0.0;
}

Stage1Metrics Stage1MetricsAccumulator::Result() const {
  Stage1Metrics r;
  r.scenes = scenes_;
  r.points = static_cast<long long>(gt_sem_.size());
  r.semantic = SemanticIou(gt_sem_, pred_sem_, num_semantic_);
  r.gt_objects = gt_objects_;
  r.gt_scenes = gt_scenes_;
  // Every class present has >= 0 objects: the present mean is the supported mean at 0.
  r.miou_present = SupportedMiou(r, 0, &r.classes_present);
  const int nc = num_semantic_;
  std::vector<long long> confusion(static_cast<std::size_t>(nc) * nc, 0);
  for (std::size_t i = 0; i < gt_sem_.size(); ++i) {
    const int g = gt_sem_[i], p = pred_sem_[i];
    if (g >= 0 && g < nc && p >= 0 && p < nc) ++confusion[static_cast<std::size_t>(g) * nc + p];
  }
  r.confused_with.assign(nc, -1);
  r.confused_share.assign(nc, 0.0);
  for (int g = 0; g < nc; ++g) {
    long long total = 0, best = 0;
    for (int p = 0; p < nc; ++p) {
      const long long v = confusion[static_cast<std::size_t>(g) * nc + p];
      total += v;
      if (p != g && v > best) {
        best = v;
        r.confused_with[g] = p;
      }
    }
    if (total > 0) r.confused_share[g] = static_cast<double>(best) / static_cast<double>(total);
  }
  r.instances = InstanceAp(inst_scenes_, num_cad_);
  if (!heading_errors_.empty()) {
    std::vector<double> h = heading_errors_;
    std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
    r.heading_error_deg = h[h.size() / 2];
  }
  return r;
}

}  // namespace dimr::eval

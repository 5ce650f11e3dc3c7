#include "dimr/eval/seg_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::eval {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}  // namespace

SemanticIouResult SemanticIou(const std::vector<int>& gt, const std::vector<int>& pred,
                              int num_classes) {
  if (gt.size() != pred.size()) {
    throw InvalidArgument("SemanticIou: " + std::to_string(gt.size()) + " GT labels but " +
                          std::to_string(pred.size()) + " predicted labels");
  }
  SemanticIouResult r;
  r.tp.assign(num_classes, 0);
  r.fp.assign(num_classes, 0);
  r.fn.assign(num_classes, 0);
  long long valid = 0, correct = 0;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    const int g = gt[i], p = pred[i];
    if (g < 0 || g >= num_classes) continue;
    ++valid;
    if (p == g) {
      ++r.tp[g];
      ++correct;
    } else {
      ++r.fn[g];
      if (p >= 0 && p < num_classes) ++r.fp[p];
    }
  }
  double sum = 0.0;
  int n = 0;
  r.iou.assign(num_classes, kNaN);
  for (int c = 0; c < num_classes; ++c) {
    const long long den = r.tp[c] + r.fp[c] + r.fn[c];
    if (den == 0) continue;
    r.iou[c] = static_cast<double>(r.tp[c]) / static_cast<double>(den);
    sum += r.iou[c];
    ++n;
  }
  r.miou = n ? sum / n : 0.0;
  r.accuracy = valid ? static_cast<double>(correct) / static_cast<double>(valid) : 0.0;
  return r;
}

InstanceApOptions::InstanceApOptions() {
  // np.append(np.arange(0.5, 0.95, 0.05), 0.25): start + i * step.
  for (int i = 0; i < 9; ++i) overlaps.push_back(0.5 + i * 0.05);
  overlaps.push_back(0.25);
}

double ScanNetAp(const std::vector<double>& y_true, const std::vector<double>& y_score,
                 int hard_false_negatives, bool has_gt, bool has_pred) {
  if (!has_gt) return kNaN;
  if (!has_pred) return 0.0;
  const std::size_t n = y_score.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return y_score[a] < y_score[b]; });
  std::vector<double> cumsum(n);
  double acc = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    acc += y_true[order[k]];
    cumsum[k] = acc;
  }
  // First index of each distinct score (np.unique(return_index=True) on the sorted scores).
  std::vector<std::size_t> uniq;
  for (std::size_t k = 0; k < n; ++k) {
    if (k == 0 || y_score[order[k]] != y_score[order[k - 1]]) uniq.push_back(k);
  }
  const double num_true = n ? cumsum.back() : 0.0;
  std::vector<double> precision(uniq.size() + 1, 0.0), recall(uniq.size() + 1, 0.0);
  for (std::size_t u = 0; u < uniq.size(); ++u) {
    const std::size_t idx = uniq[u];
    const double before = idx == 0 ? 0.0 : cumsum[idx - 1];
    const double tp = num_true - before;
    const double fp = static_cast<double>(n - idx) - tp;
    const double fn = before + hard_false_negatives;
    precision[u] = tp / (tp + fp);
    recall[u] = (tp + fn) > 0 ? tp / (tp + fn) : 0.0;
  }
  precision.back() = 1.0;
  recall.back() = 0.0;
  // stepWidths = convolve([r0, r..., 0], [-0.5, 0, 0.5], 'valid'): 0.5 * (x[i] - x[i + 2]).
  std::vector<double> conv;
  conv.push_back(recall.front());
  conv.insert(conv.end(), recall.begin(), recall.end());
  conv.push_back(0.0);
  double ap = 0.0;
  for (std::size_t i = 0; i < precision.size(); ++i) {
    ap += precision[i] * (0.5 * conv[i] - 0.5 * conv[i + 2]);
  }
  return ap;
}

namespace {

struct GtInst {
  int cls;
  long long id;  // label * 2^32 + instance (ScanNet: label * 1000 + instance)
  int vert_count;
  std::vector<std::pair<int, int>> matched_pred;  // (pred index, intersection)
};

struct PredInst {
  int cls;
  double score;
  int vert_count;
  int void_intersection;
  std::vector<std::pair<int, int>> matched_gt;  // (gt index, intersection)
};

}  // namespace

InstanceApResult InstanceAp(const std::vector<InstanceScene>& scenes, int num_classes,
                            const InstanceApOptions& opt) {
  InstanceApResult res;
  res.overlaps = opt.overlaps;
  const std::size_t no = opt.overlaps.size();
  // Per scene: GT instances (all sizes, sorted by id) and predictions with their overlaps.
  std::vector<std::vector<GtInst>> all_gt(scenes.size());
  std::vector<std::vector<PredInst>> all_pred(scenes.size());
  for (std::size_t s = 0; s < scenes.size(); ++s) {
    const InstanceScene& sc = scenes[s];
    const std::size_t np = sc.gt_label.size();
    if (sc.gt_instance.size() != np) {
      throw InvalidArgument("InstanceAp: scene " + std::to_string(s) +
                            ": gt_label and gt_instance differ in length");
    }
    std::map<std::pair<int, int>, int> index;  // (label, instance) -> gt slot
    std::vector<int> point_gt(np, -1);
    std::vector<char> is_void(np, 0);
    for (std::size_t i = 0; i < np; ++i) {
      const int l = sc.gt_label[i];
      if (l < 0 || l >= num_classes) {
        is_void[i] = 1;
        continue;
      }
      if (sc.gt_instance[i] < 0) continue;  // labelled, no instance: never a GT region
      index.emplace(std::make_pair(l, sc.gt_instance[i]), 0);
    }
    auto& gts = all_gt[s];
    for (auto& kv : index) {
      kv.second = static_cast<int>(gts.size());
      gts.push_back(GtInst{kv.first.first, 0, 0, {}});
    }
    for (std::size_t i = 0; i < np; ++i) {
      if (is_void[i] || sc.gt_instance[i] < 0) continue;
      const int g = index[{sc.gt_label[i], sc.gt_instance[i]}];
      point_gt[i] = g;
      ++gts[g].vert_count;
    }
    auto& preds = all_pred[s];
    std::vector<int> stamp(np, -1);
    for (std::size_t k = 0; k < sc.preds.size(); ++k) {
      const InstancePrediction& p = sc.preds[k];
      if (p.label < 0 || p.label >= num_classes) continue;
      PredInst pi{p.label, p.score, 0, 0, {}};
      std::map<int, int> inter;
      for (int i : p.points) {
        if (i < 0 || static_cast<std::size_t>(i) >= np) {
          throw InvalidArgument("InstanceAp: scene " + std::to_string(s) + " prediction " +
                                std::to_string(k) + " has point index " + std::to_string(i) +
                                " outside [0, " + std::to_string(np) + ")");
        }
        if (stamp[i] == static_cast<int>(k)) continue;  // duplicate index
        stamp[i] = static_cast<int>(k);
        ++pi.vert_count;
        if (is_void[i]) ++pi.void_intersection;
        if (point_gt[i] >= 0 && gts[point_gt[i]].cls == p.label) ++inter[point_gt[i]];
      }
      if (pi.vert_count < opt.min_region_size) continue;
      const int pidx = static_cast<int>(preds.size());
      for (const auto& kv : inter) {
        pi.matched_gt.emplace_back(kv.first, kv.second);
        gts[kv.first].matched_pred.emplace_back(pidx, kv.second);
      }
      preds.push_back(std::move(pi));
    }
  }

  res.gt_instances.assign(num_classes, 0);
  for (const auto& gts : all_gt) {
    for (const GtInst& g : gts) {
      if (g.vert_count >= opt.min_region_size) ++res.gt_instances[g.cls];
    }
  }
  res.ap.assign(num_classes, std::vector<double>(no, kNaN));
  for (int c = 0; c < num_classes; ++c) {
    for (std::size_t oi = 0; oi < no; ++oi) {
      const double th = opt.overlaps[oi];
      std::vector<double> y_true, y_score;
      int hard_fn = 0;
      bool has_gt = false, has_pred = false;
      for (std::size_t s = 0; s < scenes.size(); ++s) {
        const auto& gts = all_gt[s];
        const auto& preds = all_pred[s];
        std::vector<int> gt_list;
        for (std::size_t g = 0; g < gts.size(); ++g) {
          if (gts[g].cls == c && gts[g].vert_count >= opt.min_region_size) {
            gt_list.push_back(static_cast<int>(g));
          }
        }
        std::vector<int> pred_list;
        for (std::size_t p = 0; p < preds.size(); ++p) {
          if (preds[p].cls == c) pred_list.push_back(static_cast<int>(p));
        }
        has_gt |= !gt_list.empty();
        has_pred |= !pred_list.empty();
        std::vector<char> visited(preds.size(), 0);
        std::vector<double> cur_true(gt_list.size(), 1.0);
        std::vector<double> cur_score(gt_list.size(), -HUGE_VAL);
        std::vector<char> cur_match(gt_list.size(), 0);
        for (std::size_t gi = 0; gi < gt_list.size(); ++gi) {
          const GtInst& g = gts[gt_list[gi]];
          bool found = false;
          for (const auto& [p, inter] : g.matched_pred) {
            if (visited[p]) continue;
            const double overlap =
                static_cast<double>(inter) / (g.vert_count + preds[p].vert_count - inter);
            if (overlap > th) {
              const double conf = preds[p].score;
              if (cur_match[gi]) {
                const double hi = std::max(cur_score[gi], conf);
                const double lo = std::min(cur_score[gi], conf);
                cur_score[gi] = hi;
                cur_true.push_back(0.0);
                cur_score.push_back(lo);
                cur_match.push_back(1);
              } else {
                found = true;
                cur_match[gi] = 1;
                cur_score[gi] = conf;
                visited[p] = 1;
              }
            }
          }
          if (!found) ++hard_fn;
        }
        for (std::size_t k = 0; k < cur_true.size(); ++k) {
          if (!cur_match[k]) continue;
          y_true.push_back(cur_true[k]);
          y_score.push_back(cur_score[k]);
        }
        for (int p : pred_list) {
          const PredInst& pr = preds[p];
          bool found_gt = false;
          for (const auto& [g, inter] : pr.matched_gt) {
            const double overlap =
                static_cast<double>(inter) / (gts[g].vert_count + pr.vert_count - inter);
            if (overlap > th) {
              found_gt = true;
              break;
            }
          }
          if (found_gt) continue;
          double num_ignore = pr.void_intersection;
          for (const auto& [g, inter] : pr.matched_gt) {
            if (gts[g].vert_count < opt.min_region_size) num_ignore += inter;
          }
          if (num_ignore / pr.vert_count <= th) {
            y_true.push_back(0.0);
            y_score.push_back(pr.score);
          }
        }
      }
      res.ap[c][oi] = ScanNetAp(y_true, y_score, hard_fn, has_gt, has_pred);
    }
  }

  // Averages (compute_averages): per class plain average over the AP overlaps, overall nanmean.
  std::vector<std::size_t> ap_idx;
  std::size_t i50 = no, i25 = no;
  for (std::size_t oi = 0; oi < no; ++oi) {
    if (std::abs(opt.overlaps[oi] - 0.25) < 1e-9) {
      i25 = oi;
    } else {
      ap_idx.push_back(oi);
    }
    if (std::abs(opt.overlaps[oi] - 0.5) < 1e-9) i50 = oi;
  }
  auto nanmean = [](const std::vector<double>& v) {
    double s = 0.0;
    int n = 0;
    for (double x : v) {
      if (!std::isnan(x)) {
        s += x;
        ++n;
      }
    }
    return n ? s / n : kNaN;
  };
  std::vector<double> all, all50, all25;
  for (int c = 0; c < num_classes; ++c) {
    double s = 0.0;
    for (std::size_t oi : ap_idx) {
      s += res.ap[c][oi];
      all.push_back(res.ap[c][oi]);
    }
    res.class_ap.push_back(ap_idx.empty() ? kNaN : s / ap_idx.size());
    res.class_ap50.push_back(i50 < no ? res.ap[c][i50] : kNaN);
    res.class_ap25.push_back(i25 < no ? res.ap[c][i25] : kNaN);
    all50.push_back(res.class_ap50.back());
    all25.push_back(res.class_ap25.back());
  }
  res.map = nanmean(all);
  res.map50 = nanmean(all50);
  res.map25 = nanmean(all25);
  return res;
}

}  // namespace dimr::eval

#include "dimr/eval/ap.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::eval {

namespace {
constexpr double kEps = 2.220446049250313e-16;  // np.finfo(np.float64).eps
}  // namespace

double ElevenPointThreshold(int i) { return static_cast<double>(i) * 0.1; }

double Voc07Ap(const std::vector<double>& rec, const std::vector<double>& prec) {
  if (rec.size() != prec.size()) {
    throw InvalidArgument("Voc07Ap: rec and prec have different lengths");
  }
  double ap = 0.0;
  for (int i = 0; i <= 10; ++i) {
    const double t = ElevenPointThreshold(i);
    bool any = false;
    double p = 0.0;
    for (std::size_t k = 0; k < rec.size(); ++k) {
      if (rec[k] >= t) {
        p = any ? std::max(p, prec[k]) : prec[k];
        any = true;
      }
    }
    ap = ap + (any ? p : 0.0) / 11.0;
  }
  return ap;
}

std::vector<int> RankByScore(const std::vector<double>& scores) {
  std::vector<int> order(scores.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return scores[a] > scores[b]; });
  return order;
}

ClassAp EvaluateClassAp(const std::vector<RankedPrediction>& preds,
                        const std::vector<int>& gt_per_scene, double threshold, PassTest test,
                        MatchRule rule) {
  ClassAp out;
  std::vector<std::vector<char>> taken(gt_per_scene.size());
  for (std::size_t s = 0; s < gt_per_scene.size(); ++s) {
    if (gt_per_scene[s] < 0) throw InvalidArgument("EvaluateClassAp: negative GT count");
    taken[s].assign(gt_per_scene[s], 0);
    out.npos += gt_per_scene[s];
  }
  std::vector<double> scores(preds.size());
  for (std::size_t i = 0; i < preds.size(); ++i) {
    const auto& p = preds[i];
    if (p.scene < 0 || p.scene >= static_cast<int>(gt_per_scene.size())) {
      throw InvalidArgument("EvaluateClassAp: prediction " + std::to_string(i) + " has scene " +
                            std::to_string(p.scene) + " outside [0, " +
                            std::to_string(gt_per_scene.size()) + ")");
    }
    if (static_cast<int>(p.values.size()) != gt_per_scene[p.scene]) {
      throw InvalidArgument("EvaluateClassAp: prediction " + std::to_string(i) + " has " +
                            std::to_string(p.values.size()) + " metric values but its scene has " +
                            std::to_string(gt_per_scene[p.scene]) + " GT items");
    }
    scores[i] = p.score;
  }
  out.num_pred = static_cast<int>(preds.size());
  out.order = RankByScore(scores);
  const bool larger_better = test == PassTest::kGreater;
  auto better = [&](double v, double best) { return larger_better ? v > best : v < best; };
  const double init = larger_better ? -HUGE_VAL : HUGE_VAL;

  double tp = 0.0, fp = 0.0;
  const double npos = std::max(static_cast<double>(out.npos), kEps);
  for (int idx : out.order) {
    const auto& p = preds[idx];
    auto& tk = taken[p.scene];
    double best = init;
    int jbest = -1;
    for (std::size_t j = 0; j < p.values.size(); ++j) {
      if (rule == MatchRule::kBestUnmatched && tk[j]) continue;
      const double v = p.values[j];
      if (std::isnan(v)) continue;
      if (better(v, best)) {
        best = v;
        jbest = static_cast<int>(j);
      }
    }
    int matched = -1;
    if (jbest >= 0 && better(best, threshold) && !tk[jbest]) {
      tk[jbest] = 1;
      matched = jbest;
    }
    if (matched >= 0) {
      tp += 1.0;
    } else {
      fp += 1.0;
    }
    out.matched_gt.push_back(matched);
    out.rec.push_back(tp / npos);
    out.prec.push_back(tp / std::max(tp + fp, kEps));
  }
  out.tp = static_cast<int>(tp);
  out.fp = static_cast<int>(fp);
  out.ap = Voc07Ap(out.rec, out.prec);
  if (!out.prec.empty()) {
    out.precision = out.prec.back();
    out.recall = out.rec.back();
  }
  return out;
}

void FinishTable(ApTable* table) {
  double sum_ap = 0.0, sum_p = 0.0, sum_r = 0.0;
  int n = 0;
  for (int c = 0; c < kNumClasses; ++c) {
    const ClassAp& ca = table->classes[c];
    table->present[c] = ca.npos > 0 || ca.num_pred > 0;
    if (!table->present[c]) continue;
    sum_ap += ca.ap;
    sum_p += ca.precision;
    sum_r += ca.recall;
    ++n;
  }
  table->map = n ? sum_ap / n : 0.0;
  table->mean_precision = n ? sum_p / n : 0.0;
  table->mean_recall = n ? sum_r / n : 0.0;
}

}  // namespace dimr::eval

#include "dimr/pipeline/class_bias.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "dimr/geometry/error.h"

namespace dimr::pipeline {
namespace {

void CheckProb(const std::vector<float>& prob, int num_classes, const char* who) {
  if (num_classes <= 0) {
    throw InvalidArgument(std::string(who) + ": num_classes must be positive, got " +
                          std::to_string(num_classes));
  }
  if (prob.size() % static_cast<std::size_t>(num_classes) != 0) {
    throw InvalidArgument(std::string(who) + ": prob has " + std::to_string(prob.size()) +
                          " values, not a multiple of " + std::to_string(num_classes) + " classes");
  }
  for (std::size_t k = 0; k < prob.size(); ++k) {
    if (!(prob[k] >= 0.0f) || !std::isfinite(prob[k])) {
      throw InvalidArgument(std::string(who) + ": probability of point " +
                            std::to_string(k / num_classes) + ", class " +
                            std::to_string(k % num_classes) + " is " + std::to_string(prob[k]));
    }
  }
}

void CheckLabels(const std::vector<int>& labels, std::size_t n, int num_classes, const char* who,
                 const char* name) {
  if (labels.size() != n) {
    throw InvalidArgument(std::string(who) + ": " + name + " has " + std::to_string(labels.size()) +
                          " values, expected " + std::to_string(n));
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] >= num_classes) {
      throw InvalidArgument(std::string(who) + ": " + name + "[" + std::to_string(i) +
                            "] = " + std::to_string(labels[i]) + " is not below " +
                            std::to_string(num_classes));
    }
  }
}

double IoU(long long tp, long long gt, long long pred) {
  const long long uni = gt + pred - tp;
  return uni > 0 ? static_cast<double>(tp) / static_cast<double>(uni) : 0.0;
}

}  // namespace

std::vector<int> ApplyClassBias(const std::vector<float>& bias, std::vector<float>* prob,
                                int num_classes) {
  CheckProb(*prob, num_classes, "ApplyClassBias");
  if (!bias.empty() && bias.size() != static_cast<std::size_t>(num_classes)) {
    throw InvalidArgument("ApplyClassBias: bias has " + std::to_string(bias.size()) +
                          " values, expected " + std::to_string(num_classes));
  }
  std::vector<double> scale(num_classes, 1.0);
  for (int c = 0; c < static_cast<int>(bias.size()); ++c) {
    if (!std::isfinite(bias[c])) {
      throw InvalidArgument("ApplyClassBias: bias of class " + std::to_string(c) +
                            " is not finite");
    }
    scale[c] = std::exp(static_cast<double>(bias[c]));
  }
  const std::size_t n = prob->size() / num_classes;
  std::vector<int> argmax(n, 0);
  std::vector<double> w(num_classes);
  for (std::size_t i = 0; i < n; ++i) {
    float* row = prob->data() + i * num_classes;
    double sum = 0;
    for (int c = 0; c < num_classes; ++c) sum += w[c] = row[c] * scale[c];
    if (!(sum > 0)) continue;
    int best = 0;
    for (int c = 0; c < num_classes; ++c) {
      if (!bias.empty()) row[c] = static_cast<float>(w[c] / sum);
      if (w[c] > w[best]) best = c;
    }
    argmax[i] = best;
  }
  return argmax;
}

void ClassBiasFitOptions::Validate() const {
  if (!std::isfinite(min_bias) || !std::isfinite(max_bias) || !(min_bias <= 0.0) ||
      !(max_bias >= 0.0)) {
    throw InvalidArgument("ClassBiasFitOptions: the grid [min_bias, max_bias] = [" +
                          std::to_string(min_bias) + ", " + std::to_string(max_bias) +
                          "] must be finite and contain 0");
  }
  if (!(step > 0.0) || (max_bias - min_bias) / step > 1e5) {
    throw InvalidArgument(
        "ClassBiasFitOptions.step: must be positive and give <= 1e5 grid values, "
        "got " +
        std::to_string(step));
  }
  if (max_sweeps < 1) {
    throw InvalidArgument("ClassBiasFitOptions.max_sweeps: must be >= 1, got " +
                          std::to_string(max_sweeps));
  }
}

double MeanIouPresent(const std::vector<int>& labels, const std::vector<int>& pred, int num_classes,
                      std::vector<double>* per_class) {
  CheckLabels(pred, labels.size(), num_classes, "MeanIouPresent", "pred");
  CheckLabels(labels, labels.size(), num_classes, "MeanIouPresent", "labels");
  std::vector<long long> tp(num_classes, 0), gt(num_classes, 0), pc(num_classes, 0);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] < 0) continue;
    if (pred[i] < 0) {
      throw InvalidArgument("MeanIouPresent: pred[" + std::to_string(i) + "] is negative");
    }
    ++gt[labels[i]];
    ++pc[pred[i]];
    if (pred[i] == labels[i]) ++tp[labels[i]];
  }
  double sum = 0;
  int present = 0;
  if (per_class) per_class->assign(num_classes, std::numeric_limits<double>::quiet_NaN());
  for (int c = 0; c < num_classes; ++c) {
    if (gt[c] == 0) continue;
    const double v = IoU(tp[c], gt[c], pc[c]);
    if (per_class) (*per_class)[c] = v;
    sum += v;
    ++present;
  }
  return present ? sum / present : 0.0;
}

ClassBiasFit FitClassBias(const std::vector<int>& labels, const std::vector<float>& prob,
                          int num_classes, const ClassBiasFitOptions& options) {
  options.Validate();
  CheckProb(prob, num_classes, "FitClassBias");
  const int C = num_classes;
  const std::size_t n_all = prob.size() / C;
  CheckLabels(labels, n_all, C, "FitClassBias", "labels");
  // Log-probabilities of the labelled points only (the others do not enter the IoU).
  std::vector<int> gt;
  std::vector<float> logp;
  for (std::size_t i = 0; i < n_all; ++i) {
    if (labels[i] < 0) continue;
    gt.push_back(labels[i]);
    for (int c = 0; c < C; ++c) {
      logp.push_back(std::log(std::max(prob[i * C + c], 1e-30f)));
    }
  }
  const std::size_t n = gt.size();
  if (n == 0) throw InvalidArgument("FitClassBias: no labelled point");
  std::vector<long long> gt_count(C, 0);
  for (int g : gt) ++gt_count[g];
  int present = 0;
  for (int c = 0; c < C; ++c) present += gt_count[c] > 0;

  ClassBiasFit fit;
  fit.bias.assign(C, 0.0f);
  // The objective as ApplyClassBias + MeanIouPresent score it (unlabelled points ignored).
  auto score = [&](const std::vector<float>& b, std::vector<double>* per_class) {
    std::vector<float> p = prob;
    return MeanIouPresent(labels, ApplyClassBias(b, &p, C), C, per_class);
  };
  fit.miou_before = score({}, &fit.iou_before);

  const int grid_size =
      static_cast<int>(std::floor((options.max_bias - options.min_bias) / options.step + 1e-9)) + 1;
  std::vector<double> grid(grid_size);
  for (int k = 0; k < grid_size; ++k) grid[k] = options.min_bias + k * options.step;

  std::vector<int> bucket(n), alt(n);
  for (fit.sweeps = 1; fit.sweeps <= options.max_sweeps; ++fit.sweeps) {
    bool changed = false;
    for (int c = 0; c < C; ++c) {
      // Candidates: the grid plus the current value (so the objective never drops).
      std::vector<double> cand = grid;
      cand.push_back(fit.bias[c]);
      std::sort(cand.begin(), cand.end());
      cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
      const int K = static_cast<int>(cand.size());
      // Point i is predicted c for every candidate value v > margin_i (= best other score -
      // own score), i.e. for the candidates k >= bucket_i; below that it keeps alt_i.
      std::vector<long long> a_cnt(K + 1, 0), a_tp(K + 1, 0);
      std::vector<long long> b_cnt(static_cast<std::size_t>(K + 1) * C, 0),
          b_tp(static_cast<std::size_t>(K + 1) * C, 0);
      for (std::size_t i = 0; i < n; ++i) {
        const float* row = logp.data() + i * C;
        double other = -std::numeric_limits<double>::infinity();
        int a = c == 0 ? 1 : 0;
        for (int j = 0; j < C; ++j) {
          if (j == c) continue;
          const double v = static_cast<double>(row[j]) + fit.bias[j];
          if (v > other) {
            other = v;
            a = j;
          }
        }
        const double margin = other - row[c];
        const int k =
            static_cast<int>(std::upper_bound(cand.begin(), cand.end(), margin) - cand.begin());
        ++a_cnt[k];
        a_tp[k] += gt[i] == c;
        const std::size_t slot = static_cast<std::size_t>(k) * C + a;
        ++b_cnt[slot];
        b_tp[slot] += gt[i] == a;
      }
      // Suffix sums of the "alt" side (points with bucket > k keep their alt class).
      std::vector<long long> s_cnt(static_cast<std::size_t>(K + 2) * C, 0),
          s_tp(static_cast<std::size_t>(K + 2) * C, 0);
      for (int k = K; k >= 0; --k) {
        for (int j = 0; j < C; ++j) {
          const std::size_t at = static_cast<std::size_t>(k) * C + j;
          s_cnt[at] = s_cnt[at + C] + b_cnt[at];
          s_tp[at] = s_tp[at + C] + b_tp[at];
        }
      }
      long long pc = 0, ptp = 0;
      int best_k = -1;
      double best_obj = -1, cur_obj = -1;
      for (int k = 0; k < K; ++k) {
        pc += a_cnt[k];
        ptp += a_tp[k];
        double sum = 0;
        for (int j = 0; j < C; ++j) {
          if (gt_count[j] == 0) continue;
          const std::size_t at = static_cast<std::size_t>(k + 1) * C + j;
          sum += j == c ? IoU(ptp, gt_count[j], pc) : IoU(s_tp[at], gt_count[j], s_cnt[at]);
        }
        const double obj = sum / present;
        const bool is_current = cand[k] == static_cast<double>(fit.bias[c]);
        if (is_current) cur_obj = obj;
        // Strictly better, or as good and closer to zero (a smaller correction).
        if (best_k < 0 || obj > best_obj + 1e-12 ||
            (obj > best_obj - 1e-12 && std::abs(cand[k]) < std::abs(cand[best_k]))) {
          best_k = k;
          best_obj = obj;
        }
      }
      if (best_obj > cur_obj + 1e-12 && static_cast<float>(cand[best_k]) != fit.bias[c]) {
        fit.bias[c] = static_cast<float>(cand[best_k]);
        changed = true;
      }
    }
    if (!changed) break;
  }
  fit.sweeps = std::min(fit.sweeps, options.max_sweeps);
  fit.miou_after = score(fit.bias, &fit.iou_after);
  return fit;
}

}  // namespace dimr::pipeline

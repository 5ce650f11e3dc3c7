#include "dimr/eval/report.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "dimr/geometry/error.h"

namespace dimr::eval {

namespace {

std::string Fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string Pct(double v) { return Fmt("%.2f", 100.0 * v); }

std::string ThresholdName(const ApTable& t) {
  if (t.metric == "lfd") return Fmt("%.0f", t.threshold);
  return Fmt("%g", t.threshold);
}

std::string Title(const ApTable& t) {
  std::string m = t.metric == "iou"   ? "IoU"
                  : t.metric == "cd"  ? "CD"
                  : t.metric == "lfd" ? "LFD"
                                      : "PCR";
  return m + "@" + ThresholdName(t);
}

}  // namespace

std::string FormatMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "## dimr eval (protocol: " << ProtocolName(r.protocol) << ")\n\n";
  o << "Scenes " << r.num_scenes << ", GT meshes " << r.num_gt << ", predictions " << r.num_preds;
  if (r.dropped_preds) o << " (+" << r.dropped_preds << " dropped: scene without GT)";
  if (r.num_pcr_scenes) {
    o << "; PCR scenes " << r.num_pcr_scenes << ", PCR GT instances " << r.num_pcr_gt;
  }
  o << ".\n\n";
  // Table 1: completion quality (mAP, %).
  bool any_mesh = false;
  for (const ApTable& t : r.tables) any_mesh |= t.metric != "pcr";
  if (any_mesh) {
    o << "### Completion quality: mAP (%) (paper Table 1)\n\n|";
    for (const ApTable& t : r.tables) {
      if (t.metric != "pcr") o << " " << Title(t) << " |";
    }
    o << "\n|";
    for (const ApTable& t : r.tables) {
      if (t.metric != "pcr") o << "---|";
    }
    o << "\n|";
    for (const ApTable& t : r.tables) {
      if (t.metric != "pcr") o << " " << Pct(t.map) << " |";
    }
    o << "\n\n";
  }
  // Table 2: PCR per class.
  for (const ApTable& t : r.tables) {
    if (t.metric != "pcr") continue;
    o << "### Mapping quality: AP at PCR@0.5, omega = 0.047 m (paper Table 2)\n\n|";
    for (int c = 0; c < kNumClasses; ++c) o << " " << ClassNames()[c] << " |";
    o << " mean |\n|";
    for (int c = 0; c <= kNumClasses; ++c) o << "---|";
    o << "\n|";
    for (int c = 0; c < kNumClasses; ++c) o << " " << Pct(t.classes[c].ap) << " |";
    o << " " << Pct(t.map) << " |\n\n";
  }
  // Table 3: recognition precision at IoU thresholds.
  const ApTable* p25 = r.Find("iou", 0.25);
  const ApTable* p50 = r.Find("iou", 0.5);
  if (p25 && p50) {
    o << "### Object recognition precision: mean final precision (%) (paper Table 3)\n\n"
      << "| Prec.@0.25 | Prec.@0.5 |\n|---|---|\n| " << Pct(p25->mean_precision) << " | "
      << Pct(p50->mean_precision) << " |\n\n";
  }
  // Per-class tables.
  for (const ApTable& t : r.tables) {
    o << "### " << Title(t)
      << " per class\n\n| class | npos | preds | TP | AP | precision | recall |\n"
      << "|---|---|---|---|---|---|---|\n";
    for (int c = 0; c < kNumClasses; ++c) {
      const ClassAp& a = t.classes[c];
      o << "| " << ClassNames()[c] << (t.present[c] ? "" : " (absent)") << " | " << a.npos << " | "
        << a.num_pred << " | " << a.tp << " | " << Pct(a.ap) << " | " << Pct(a.precision) << " | "
        << Pct(a.recall) << " |\n";
    }
    o << "| **mean** | | | | **" << Pct(t.map) << "** | " << Pct(t.mean_precision) << " | "
      << Pct(t.mean_recall) << " |\n\n";
  }
  if (!r.warnings.empty()) {
    o << "Warnings:\n";
    for (const std::string& w : r.warnings) o << "- " << w << "\n";
    o << "\n";
  }
  o << "Time: " << Fmt("%.2f", r.total_seconds) << " s on " << r.threads << " thread(s) (";
  for (std::size_t i = 0; i < r.timings.size(); ++i) {
    o << (i ? ", " : "") << r.timings[i].stage << " " << Fmt("%.2f", r.timings[i].seconds) << " s";
  }
  o << ")";
  if (r.lfd_descriptors) {
    o << "; LFD " << r.lfd_descriptors << " descriptors, " << Fmt("%.1f", r.lfd_ms_per_descriptor)
      << " ms each per thread";
  }
  o << ".\n";
  return o.str();
}

std::string FormatObjectsMarkdown(const EvalReport& r) {
  std::ostringstream o;
  o << "### Per GT object: best value over the predictions of its scene and class\n\n"
    << "| scene | GT mesh | class | best IoU | (prediction) | best CD | best LFD |\n"
    << "|---|---|---|---|---|---|---|\n";
  auto num = [](double v, const char* f) { return std::isnan(v) ? std::string("-") : Fmt(f, v); };
  for (const GtObjectResult& g : r.objects) {
    o << "| " << g.scene << " | " << g.name << " | "
      << (g.cls >= 0 && g.cls < kNumClasses ? ClassNames()[g.cls] : "?") << " | "
      << num(g.best_iou, "%.3f") << " | " << (g.best_iou_name.empty() ? "-" : g.best_iou_name)
      << " | " << num(g.best_cd, "%.4f") << " | " << num(g.best_lfd, "%.0f") << " |\n";
  }
  return o.str();
}

std::string FormatJson(const EvalReport& r) {
  nlohmann::json j;
  j["protocol"] = ProtocolName(r.protocol);
  j["counts"] = {{"scenes", r.num_scenes},
                 {"gt_meshes", r.num_gt},
                 {"predictions", r.num_preds},
                 {"dropped_predictions", r.dropped_preds},
                 {"pcr_scenes", r.num_pcr_scenes},
                 {"pcr_gt", r.num_pcr_gt},
                 {"pcr_predictions", r.num_pcr_preds},
                 {"dropped_pcr_predictions", r.dropped_pcr_preds}};
  j["tables"] = nlohmann::json::array();
  for (const ApTable& t : r.tables) {
    nlohmann::json jt;
    jt["metric"] = t.metric;
    jt["threshold"] = t.threshold;
    jt["mAP"] = t.map;
    jt["mean_precision"] = t.mean_precision;
    jt["mean_recall"] = t.mean_recall;
    jt["classes"] = nlohmann::json::object();
    for (int c = 0; c < kNumClasses; ++c) {
      const ClassAp& a = t.classes[c];
      jt["classes"][ClassNames()[c]] = {{"present", static_cast<bool>(t.present[c])},
                                        {"AP", a.ap},
                                        {"precision", a.precision},
                                        {"recall", a.recall},
                                        {"npos", a.npos},
                                        {"predictions", a.num_pred},
                                        {"tp", a.tp},
                                        {"fp", a.fp},
                                        {"curve_recall", a.rec},
                                        {"curve_precision", a.prec}};
    }
    j["tables"].push_back(jt);
  }
  j["objects"] = nlohmann::json::array();
  auto num = [](double v) { return std::isnan(v) ? nlohmann::json() : nlohmann::json(v); };
  for (const GtObjectResult& g : r.objects) {
    j["objects"].push_back({{"scene", g.scene},
                            {"gt", g.name},
                            {"class", g.cls >= 0 && g.cls < kNumClasses ? ClassNames()[g.cls] : ""},
                            {"best_iou", num(g.best_iou)},
                            {"best_iou_prediction", g.best_iou_name},
                            {"best_cd", num(g.best_cd)},
                            {"best_lfd", num(g.best_lfd)}});
  }
  j["warnings"] = r.warnings;
  nlohmann::json tm = nlohmann::json::object();
  for (const StageTiming& s : r.timings) tm[s.stage] = s.seconds;
  tm["total"] = r.total_seconds;
  j["timing_seconds"] = tm;
  j["threads"] = r.threads;
  j["lfd_descriptors_computed"] = r.lfd_descriptors;
  j["lfd_ms_per_descriptor"] = r.lfd_ms_per_descriptor;
  return j.dump(1);
}

std::string PrCurveSvg(const ApTable& t) {
  static const char* kColours[kNumClasses] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                              "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"};
  const double x0 = 60, y0 = 20, w = 400, h = 300;  // plot area
  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"640\" height=\"370\" "
       "font-family=\"sans-serif\" font-size=\"12\">\n"
    << "<rect width=\"640\" height=\"370\" fill=\"white\"/>\n"
    << "<text x=\"" << x0 + w / 2 << "\" y=\"14\" text-anchor=\"middle\">Precision-recall, "
    << Title(t) << " (mAP " << Pct(t.map) << "%)</text>\n"
    << "<rect x=\"" << x0 << "\" y=\"" << y0 << "\" width=\"" << w << "\" height=\"" << h
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  for (int i = 0; i <= 10; i += 2) {
    const double fx = x0 + w * i / 10.0, fy = y0 + h - h * i / 10.0;
    o << "<line x1=\"" << fx << "\" y1=\"" << y0 << "\" x2=\"" << fx << "\" y2=\"" << y0 + h
      << "\" stroke=\"#ddd\"/>\n<line x1=\"" << x0 << "\" y1=\"" << fy << "\" x2=\"" << x0 + w
      << "\" y2=\"" << fy << "\" stroke=\"#ddd\"/>\n"
      << "<text x=\"" << fx << "\" y=\"" << y0 + h + 15 << "\" text-anchor=\"middle\">"
      << Fmt("%.1f", i / 10.0) << "</text>\n<text x=\"" << x0 - 5 << "\" y=\"" << fy + 4
      << "\" text-anchor=\"end\">" << Fmt("%.1f", i / 10.0) << "</text>\n";
  }
  o << "<text x=\"" << x0 + w / 2 << "\" y=\"" << y0 + h + 32
    << "\" text-anchor=\"middle\">recall</text>\n<text x=\"15\" y=\"" << y0 + h / 2
    << "\" transform=\"rotate(-90 15 " << y0 + h / 2
    << ")\" text-anchor=\"middle\">precision</text>\n";
  int legend = 0;
  for (int c = 0; c < kNumClasses; ++c) {
    const ClassAp& a = t.classes[c];
    if (!t.present[c]) continue;
    if (!a.rec.empty()) {
      o << "<polyline fill=\"none\" stroke=\"" << kColours[c]
        << "\" stroke-width=\"1.5\" points=\"";
      for (std::size_t k = 0; k < a.rec.size(); ++k) {
        const double px = x0 + w * std::min(1.0, a.rec[k]);
        const double py = y0 + h - h * std::min(1.0, a.prec[k]);
        o << Fmt("%.2f", px) << "," << Fmt("%.2f", py) << (k + 1 < a.rec.size() ? " " : "");
      }
      o << "\"/>\n";
    }
    const double ly = y0 + 10 + 18 * legend++;
    o << "<line x1=\"" << x0 + w + 15 << "\" y1=\"" << ly << "\" x2=\"" << x0 + w + 35 << "\" y2=\""
      << ly << "\" stroke=\"" << kColours[c] << "\" stroke-width=\"2\"/>\n"
      << "<text x=\"" << x0 + w + 40 << "\" y=\"" << ly + 4 << "\">" << ClassNames()[c] << " "
      << Pct(a.ap) << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

int WritePrCurvesSvg(const EvalReport& r, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InvalidArgument("cannot create SVG folder " + dir + ": " + ec.message());
  int n = 0;
  for (const ApTable& t : r.tables) {
    const std::string path = dir + "/" + t.metric + "_" + ThresholdName(t) + ".svg";
    std::ofstream out(path);
    if (!out) throw InvalidArgument("cannot write " + path);
    out << PrCurveSvg(t);
    ++n;
  }
  return n;
}

}  // namespace dimr::eval

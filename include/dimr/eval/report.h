// Reports of an evaluation: a Markdown/terminal table laid out like the paper's Tables 1-3,
// JSON with every number, and SVG precision-recall curves.
#pragma once

#include <string>

#include "dimr/eval/evaluator.h"

namespace dimr::eval {

// Table 1 (mAP per metric and threshold), Table 2 (PCR AP per class), Table 3 (mean
// precision at the IoU thresholds), then per-class AP / precision / recall tables and notes.
std::string FormatMarkdown(const EvalReport& report);
// Per GT mesh (EvalReport::objects): its best IoU (and which prediction), CD and LFD over the
// predictions of its scene and class; "-" where there is none. For a handful of scenes (a real
// room): what keeps each object from counting.
std::string FormatObjectsMarkdown(const EvalReport& report);
// Every number: per table and class AP, precision, recall, npos, predictions, TP, FP, the PR
// curve; means; counts; per-object best values ("objects"); warnings; timings.
std::string FormatJson(const EvalReport& report);
// One SVG per table (`<metric>_<threshold>.svg`, one curve per class with predictions) into
// `dir` (created). Returns the number of files written.
int WritePrCurvesSvg(const EvalReport& report, const std::string& dir);
// The SVG document of one table.
std::string PrCurveSvg(const ApTable& table);

}  // namespace dimr::eval

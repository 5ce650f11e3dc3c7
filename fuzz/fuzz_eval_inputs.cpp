// dimr-fuzz-libs: dimr_eval
// Fuzz target for the evaluation's input parsers: the reference file-name parser and the
// SceneResult JSON parser. The first byte selects the parser; every input must either parse
// or throw dimr::Error. Any other exception or a crash is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "dimr/eval/classes.h"
#include "dimr/eval/inputs.h"
#include "dimr/geometry/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    if (data[0] & 1) {
      const auto r = dimr::eval::ParseReferenceName(text);
      if (r.cls < 0 || r.cls >= dimr::eval::kNumClasses || r.scene.size() != 12) __builtin_trap();
    } else {
      const auto recs = dimr::eval::ParseSceneResultJson(text, "fuzz.json", "/tmp");
      for (const auto& r : recs) {
        if (r.cls < 0 || r.cls >= dimr::eval::kNumClasses) __builtin_trap();
      }
    }
  } catch (const dimr::Error&) {
  }
  return 0;
}

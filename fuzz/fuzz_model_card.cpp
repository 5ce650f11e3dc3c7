// dimr-fuzz-libs: dimr_pipeline
// Fuzz target for the model-card reader (pipeline::ModelCard, yaml-cpp): every input must
// either parse or throw dimr::Error, and every getter on every key of a parsed card must return
// or throw dimr::Error. Any other exception, a crash or a sanitizer report is a finding.
#include <cstddef>
#include <cstdint>
#include <string>

#include "dimr/core/error.h"
#include "dimr/pipeline/model_card.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dimr::pipeline::ModelCard card;
  try {
    card = dimr::pipeline::ModelCard::Parse(std::string(reinterpret_cast<const char*>(data), size),
                                            "fuzz.yaml");
  } catch (const dimr::Error&) {
    return 0;
  }
  for (const std::string& key : card.Keys()) {
    if (!card.has(key)) __builtin_trap();  // Keys() and has() disagree
    try {
      card.GetString(key);
    } catch (const dimr::Error&) {
    }
    try {
      card.GetDouble(key, 0.0);
    } catch (const dimr::Error&) {
    }
    try {
      card.GetInt(key, 0);
    } catch (const dimr::Error&) {
    }
    try {
      card.GetBool(key, false);
    } catch (const dimr::Error&) {
    }
    try {
      card.GetDoubleList(key);
    } catch (const dimr::Error&) {
    }
  }
  return 0;
}

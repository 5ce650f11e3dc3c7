#include "dimr/pipeline/scene_result.h"

namespace dimr::pipeline {

const char* MeshSourceName(MeshSource source) {
  switch (source) {
    case MeshSource::kGenerated:
      return "generated";
    case MeshSource::kProjected:
      return "projected";
    case MeshSource::kRetrieved:
      return "retrieved";
  }
  return "?";
}

}  // namespace dimr::pipeline

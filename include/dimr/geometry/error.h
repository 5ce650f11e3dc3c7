// Forwarding header: the error types live in the core layer (dimr/core/error.h) since every
// layer, nn included, throws them. Kept so that existing includes stay valid.
#pragma once

#include "dimr/core/error.h"

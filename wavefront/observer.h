// The PathObserver interface moved to core/path_observer.h so that the
// radiance recorder (core only) can implement it; kept for includes.
#pragma once

#include "core/path_observer.h"

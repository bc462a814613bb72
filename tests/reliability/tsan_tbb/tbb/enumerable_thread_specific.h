#pragma once
// ThreadSanitizer build only: see hmap_tsan_tbb.h.
#include "hmap_tsan_tbb.h"

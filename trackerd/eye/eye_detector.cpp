#include "eye/eye_detector.h"
// Being written (step 4).

#include "eye/synthetic_eye.h"
// Being written (step 4).

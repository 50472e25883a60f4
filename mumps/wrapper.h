#include <dmumps_c.h>

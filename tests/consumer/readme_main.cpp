// The README snippet compiled as C++ (links only if att.h has its extern "C" guard).
#include "readme_main.c"

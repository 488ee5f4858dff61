/* The one header bindgen reads: Embree 4 when build.rs found it, else Embree 3. */
#ifdef CUTICLE_EMBREE4
#include <embree4/rtcore.h>
#else
#include <embree3/rtcore.h>
#endif

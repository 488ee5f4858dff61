// OpenImageIO shim (stub: being written).
#include <OpenImageIO/imageio.h>
extern "C" int cuticle_oiio_version() { return OIIO_VERSION; }

/* A small C API over OpenImageIO (2.4 and later) for cuticle.
 *
 * Mirrored by hand in src/sys/oiio.rs: keep the two in step.
 *
 * Conventions:
 * - Paths and channel names are NUL-terminated UTF-8.
 * - Pixels are interleaved, scanline after scanline, top row first: pixel (x, y) channel c sits at
 *   index (y * width + x) * nchannels + c.
 * - Functions that can fail return 0 on success (or a non-null handle) and, on failure, write a
 *   NUL-terminated message into the caller's buffer `err` of `err_cap` bytes (truncated if longer;
 *   nothing is written when `err` is null or `err_cap` is 0).
 * - No C++ exception crosses this boundary: every entry point catches everything.
 */
#ifndef CUTICLE_OIIO_SHIM_H
#define CUTICLE_OIIO_SHIM_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Pixel formats, used both for memory buffers and for the format stored in a file. */
enum {
    CUTICLE_OIIO_FLOAT = 0, /* 32-bit IEEE float */
    CUTICLE_OIIO_HALF = 1,  /* 16-bit IEEE half float */
    CUTICLE_OIIO_UINT8 = 2  /* 8-bit unsigned, 0..255 meaning 0..1 */
};

/* Flags for cuticle_oiio_write_window. */
enum {
    /* The colour channels are not premultiplied by alpha: stop OIIO from dividing them by alpha when
     * writing a format with unassociated alpha (PNG). */
    CUTICLE_OIIO_UNASSOCIATED_ALPHA = 1
};

/* The OpenImageIO version linked, as OIIO_VERSION (e.g. 20407 for 2.4.7). */
int cuticle_oiio_version(void);

/* Where a written image sits in its full frame (an EXR data window inside the display window): pixel
 * (0, 0) of the data lands on pixel (x, y) of a `full_width` x `full_height` frame. */
typedef struct CuticleOiioWindow {
    int x;
    int y;
    int full_width;
    int full_height;
} CuticleOiioWindow;

/* Writes one image to `path`; the file format follows the extension of `path`.
 *
 * `pixels` holds width * height * nchannels values of `pixel_format`; the file stores
 * `file_format` (OIIO converts, clamping and rounding when narrowing to UINT8). `channel_names`
 * holds nchannels names. A channel named "A" becomes the alpha channel and one named "Z" the depth
 * channel. The data sits at `window` in a larger frame (null = the image is the whole frame), and
 * `nattrs` string attributes (`attr_names[i]` = `attr_values[i]`) are written as file metadata.
 * Returns 0 on success. */
int cuticle_oiio_write_window(const char *path, int width, int height, int nchannels,
                              const char *const *channel_names, const void *pixels,
                              int pixel_format, int file_format, unsigned flags,
                              const CuticleOiioWindow *window, int nattrs,
                              const char *const *attr_names, const char *const *attr_values,
                              char *err, size_t err_cap);

/* An open image file, read with the functions below and released with cuticle_oiio_close. */
typedef struct CuticleOiioInput CuticleOiioInput;

/* Opens `path` (any format OIIO reads; the first subimage, top MIP level). Returns null on failure.
 * Deep and volume images are refused. */
CuticleOiioInput *cuticle_oiio_open(const char *path, char *err, size_t err_cap);

/* The size of the image's data window and its channel count. */
void cuticle_oiio_input_size(const CuticleOiioInput *input, int *width, int *height,
                             int *nchannels);

/* The data window of the image within its full (display) window. */
void cuticle_oiio_input_window(const CuticleOiioInput *input, CuticleOiioWindow *window);

/* Copies the string attribute `name` (NUL-terminated) into `out` of `out_cap` bytes. Returns its
 * length, -1 when the file has no such string attribute, -2 when it does not fit. */
int cuticle_oiio_input_attribute(const CuticleOiioInput *input, const char *name, char *out,
                                 size_t out_cap);

/* The name of channel `channel` (0 <= channel < nchannels), valid until cuticle_oiio_close; null
 * when out of range. */
const char *cuticle_oiio_input_channel_name(const CuticleOiioInput *input, int channel);

/* Reads all pixels of all channels, converted to 32-bit float, into `out`, which holds `out_len`
 * floats: exactly width * height * nchannels. Returns 0 on success. */
int cuticle_oiio_read_float(CuticleOiioInput *input, float *out, size_t out_len, char *err,
                            size_t err_cap);

/* Closes the file and frees `input`; null is ignored. */
void cuticle_oiio_close(CuticleOiioInput *input);

#ifdef __cplusplus
}
#endif

#endif /* CUTICLE_OIIO_SHIM_H */

// The C API of oiio_shim.h over OpenImageIO's ImageOutput and ImageInput.
//
// Every entry point catches every exception: unwinding into Rust is undefined behaviour.

#include "oiio_shim.h"

#include <OpenImageIO/imageio.h>

#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <string_view>

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

struct CuticleOiioInput {
    std::unique_ptr<ImageInput> input;
    ImageSpec spec;
};

namespace {

// Appends `part` to the NUL-terminated message in the caller's buffer, truncated and always NUL-terminated.
// Allocates nothing, so it cannot throw.
void append_error(char *err, size_t err_cap, std::string_view part) noexcept {
    if (err == nullptr || err_cap == 0) {
        return;
    }
    const size_t used = strnlen(err, err_cap - 1);
    const size_t room = err_cap - 1 - used;
    const size_t n = part.size() < room ? part.size() : room;
    std::memcpy(err + used, part.data(), n);
    err[used + n] = '\0';
}

// Copies `message` into the caller's buffer, truncated and always NUL-terminated. Allocates nothing (a
// `string_view` of a literal or of a `std::string` the caller built), so it cannot throw.
void set_error(char *err, size_t err_cap, std::string_view message) noexcept {
    if (err == nullptr || err_cap == 0) {
        return;
    }
    err[0] = '\0';
    append_error(err, err_cap, message);
}

// Reports the exception being handled; call only inside a catch block. The message is assembled in the caller's
// buffer without allocating: this runs after an exception, which may be std::bad_alloc, and an exception leaving
// this noexcept function would terminate the process.
void set_exception_error(char *err, size_t err_cap, const char *what_failed) noexcept {
    set_error(err, err_cap, what_failed);
    append_error(err, err_cap, ": ");
    try {
        throw;
    } catch (const std::exception &e) {
        const char *what = e.what();
        append_error(err, err_cap, what != nullptr ? what : "unknown C++ exception");
    } catch (...) {
        append_error(err, err_cap, "unknown C++ exception");
    }
}

// OIIO's message, or `fallback` when it left none.
std::string or_fallback(std::string message, const char *fallback) {
    return message.empty() ? std::string(fallback) : message;
}

bool type_desc(int format, TypeDesc *out) {
    switch (format) {
    case CUTICLE_OIIO_FLOAT: *out = TypeDesc::FLOAT; return true;
    case CUTICLE_OIIO_HALF: *out = TypeDesc::HALF; return true;
    case CUTICLE_OIIO_UINT8: *out = TypeDesc::UINT8; return true;
    default: return false;
    }
}

}  // namespace

extern "C" int cuticle_oiio_version(void) { return OIIO_VERSION; }

namespace {

// The body of cuticle_oiio_write_window: `window` may be null (the data window is
// the whole image) and `nattrs` string attributes are written as file metadata.
int write_image(const char *path, int width, int height, int nchannels,
                const char *const *channel_names, const void *pixels, int pixel_format,
                int file_format, unsigned flags, const CuticleOiioWindow *window, int nattrs,
                const char *const *attr_names, const char *const *attr_values, char *err,
                size_t err_cap) {
    try {
        TypeDesc memory_type, file_type;
        if (!type_desc(pixel_format, &memory_type) || !type_desc(file_format, &file_type)) {
            set_error(err, err_cap, "unknown pixel format");
            return 1;
        }
        if (path == nullptr || channel_names == nullptr || pixels == nullptr || width <= 0 ||
            height <= 0 || nchannels <= 0) {
            set_error(err, err_cap, "invalid arguments (null pointer or empty image)");
            return 1;
        }
        std::unique_ptr<ImageOutput> out = ImageOutput::create(path);
        if (!out) {
            set_error(err, err_cap,
                      or_fallback(OIIO::geterror(), "no OpenImageIO writer for this file type"));
            return 1;
        }
        ImageSpec spec(width, height, nchannels, file_type);
        spec.channelnames.clear();
        spec.alpha_channel = -1;
        spec.z_channel = -1;
        for (int c = 0; c < nchannels; ++c) {
            if (channel_names[c] == nullptr) {
                set_error(err, err_cap, "null channel name");
                return 1;
            }
            spec.channelnames.emplace_back(channel_names[c]);
            if (spec.channelnames.back() == "A") {
                spec.alpha_channel = c;
            } else if (spec.channelnames.back() == "Z") {
                spec.z_channel = c;
            }
        }
        if (flags & CUTICLE_OIIO_UNASSOCIATED_ALPHA) {
            spec.attribute("oiio:UnassociatedAlpha", 1);
        }
        if (file_type == TypeDesc::UINT8) {
            // 8-bit output is display-referred: the caller has sRGB-encoded it (OIIO does not).
            spec.attribute("oiio:ColorSpace", "sRGB");
        } else {
            spec.attribute("oiio:ColorSpace", "Linear");
        }
        if (window != nullptr) {
            if (window->full_width < width || window->full_height < height || window->x < 0 ||
                window->y < 0 || window->x > window->full_width - width ||
                window->y > window->full_height - height) {
                set_error(err, err_cap, "data window lies outside the full image");
                return 1;
            }
            spec.x = window->x;
            spec.y = window->y;
            spec.full_x = 0;
            spec.full_y = 0;
            spec.full_width = window->full_width;
            spec.full_height = window->full_height;
        }
        if (nattrs < 0 || (nattrs > 0 && (attr_names == nullptr || attr_values == nullptr))) {
            set_error(err, err_cap, "invalid attribute list");
            return 1;
        }
        for (int i = 0; i < nattrs; ++i) {
            if (attr_names[i] == nullptr || attr_values[i] == nullptr) {
                set_error(err, err_cap, "null attribute name or value");
                return 1;
            }
            spec.attribute(attr_names[i], attr_values[i]);
        }
        if (!out->open(path, spec)) {
            set_error(err, err_cap, or_fallback(out->geterror(), "could not open for writing"));
            return 1;
        }
        if (!out->write_image(memory_type, pixels)) {
            std::string message = or_fallback(out->geterror(), "could not write pixels");
            out->close();
            set_error(err, err_cap, message);
            return 1;
        }
        if (!out->close()) {
            set_error(err, err_cap, or_fallback(out->geterror(), "could not close the file"));
            return 1;
        }
        return 0;
    } catch (...) {
        set_exception_error(err, err_cap, "openimageio write");
        return 1;
    }
}

}  // namespace

extern "C" int cuticle_oiio_write_window(const char *path, int width, int height, int nchannels,
                                         const char *const *channel_names, const void *pixels,
                                         int pixel_format, int file_format, unsigned flags,
                                         const CuticleOiioWindow *window, int nattrs,
                                         const char *const *attr_names,
                                         const char *const *attr_values, char *err,
                                         size_t err_cap) {
    return write_image(path, width, height, nchannels, channel_names, pixels, pixel_format,
                       file_format, flags, window, nattrs, attr_names, attr_values, err, err_cap);
}

extern "C" CuticleOiioInput *cuticle_oiio_open(const char *path, char *err, size_t err_cap) {
    try {
        if (path == nullptr) {
            set_error(err, err_cap, "null path");
            return nullptr;
        }
        std::unique_ptr<ImageInput> input = ImageInput::open(path);
        if (!input) {
            set_error(err, err_cap, or_fallback(OIIO::geterror(), "could not open for reading"));
            return nullptr;
        }
        const ImageSpec &spec = input->spec();
        if (spec.deep) {
            set_error(err, err_cap, "deep images are not supported");
            return nullptr;
        }
        if (spec.depth > 1) {
            set_error(err, err_cap, "volume images are not supported");
            return nullptr;
        }
        if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 ||
            static_cast<int>(spec.channelnames.size()) != spec.nchannels) {
            set_error(err, err_cap, "empty image or inconsistent channel list");
            return nullptr;
        }
        auto result = std::make_unique<CuticleOiioInput>();
        result->spec = spec;
        result->input = std::move(input);
        return result.release();
    } catch (...) {
        set_exception_error(err, err_cap, "openimageio open");
        return nullptr;
    }
}

extern "C" void cuticle_oiio_input_size(const CuticleOiioInput *input, int *width, int *height,
                                        int *nchannels) {
    // Plain field reads: nothing here can throw.
    if (input == nullptr) {
        return;
    }
    if (width != nullptr) {
        *width = input->spec.width;
    }
    if (height != nullptr) {
        *height = input->spec.height;
    }
    if (nchannels != nullptr) {
        *nchannels = input->spec.nchannels;
    }
}

extern "C" void cuticle_oiio_input_window(const CuticleOiioInput *input,
                                          CuticleOiioWindow *window) {
    // Plain field reads: nothing here can throw.
    if (input == nullptr || window == nullptr) {
        return;
    }
    window->x = input->spec.x - input->spec.full_x;
    window->y = input->spec.y - input->spec.full_y;
    window->full_width = input->spec.full_width;
    window->full_height = input->spec.full_height;
}

extern "C" int cuticle_oiio_input_attribute(const CuticleOiioInput *input, const char *name,
                                            char *out, size_t out_cap) {
    try {
        if (input == nullptr || name == nullptr) {
            return -1;
        }
        const OIIO::ParamValue *p = input->spec.find_attribute(name, TypeDesc::STRING);
        if (p == nullptr) {
            return -1;
        }
        const std::string value = p->get_string();
        set_error(out, out_cap, value);
        return value.size() < out_cap ? static_cast<int>(value.size()) : -2;
    } catch (...) {
        return -1;
    }
}

extern "C" const char *cuticle_oiio_input_channel_name(const CuticleOiioInput *input,
                                                       int channel) {
    // Bounds-checked index into a vector that outlives the returned pointer: nothing can throw.
    if (input == nullptr || channel < 0 ||
        static_cast<size_t>(channel) >= input->spec.channelnames.size()) {
        return nullptr;
    }
    return input->spec.channelnames[static_cast<size_t>(channel)].c_str();
}

extern "C" int cuticle_oiio_read_float(CuticleOiioInput *input, float *out, size_t out_len,
                                       char *err, size_t err_cap) {
    try {
        if (input == nullptr || out == nullptr) {
            set_error(err, err_cap, "null input or output buffer");
            return 1;
        }
        const ImageSpec &spec = input->spec;
        const size_t needed = static_cast<size_t>(spec.width) * static_cast<size_t>(spec.height) *
                              static_cast<size_t>(spec.nchannels);
        if (out_len != needed) {
            set_error(err, err_cap, "output buffer has the wrong size");
            return 1;
        }
        if (!input->input->read_image(0, 0, 0, spec.nchannels, TypeDesc::FLOAT, out)) {
            set_error(err, err_cap, or_fallback(input->input->geterror(), "could not read pixels"));
            return 1;
        }
        return 0;
    } catch (...) {
        set_exception_error(err, err_cap, "openimageio read");
        return 1;
    }
}

extern "C" void cuticle_oiio_close(CuticleOiioInput *input) {
    try {
        // Owned inside the `try`, so that `input` is freed even if close() throws and so that the ImageInput's
        // destructor (which closes the file again) runs inside the `try` as well.
        std::unique_ptr<CuticleOiioInput> owned(input);
        if (owned) {
            owned->input->close();
        }
        owned.reset();
    } catch (...) {
        // Nothing to report to: the pixels are read already, and unwinding into Rust is not allowed.
    }
}

// Coarse OpenImageIO shim for rangewalk: whole-file reads and writes on the
// plain structs shared through the cxx bridge in src/image/oiio.rs.
// Every function reports failure by throwing std::runtime_error whose message
// starts with the file name; cxx turns it into a Rust error.
#pragma once

#include "rust/cxx.h"

#include <cstddef>
#include <cstdint>
#include <exception>
#include <memory>
#include <vector>

// cxx's own handler catches std::exception only; anything else thrown
// through a bridged call would cross into Rust, which is undefined. This
// replaces it (cxx looks it up by this name) so that every exception
// becomes a Rust error.
namespace rust {
namespace behavior {
template <typename Try, typename Fail>
static void trycatch(Try &&func, Fail &&fail) noexcept try {
    func();
} catch (const std::exception &e) {
    fail(e.what());
} catch (...) {
    fail("OpenImageIO threw an exception that is not a std::exception");
}
}  // namespace behavior
}  // namespace rust

namespace rangewalk {
namespace oiio {

struct Raster;
struct Decoded;

// The channels of a file read, one vector each, so that the reader can
// free each one once it has taken it.
struct Words {
    std::vector<std::unique_ptr<uint32_t[]>> channels;
    size_t pixels = 0;
    rust::Slice<const uint32_t> channel(size_t c) const;
    void release(size_t c);
};

// Writes every channel of `image` and its attributes to `path` in the
// named OpenImageIO format ("openexr", "hdr", ...).
void write_image(rust::Str path, rust::Str format, const Raster &image);

// Reads the first subimage of `path`, refused when it has more than
// `max_pixels` pixels: 32-bit unsigned channels verbatim,
// every other channel converted to float (integer formats normalized to
// [0, 1]), plus the float and string attributes of its header. The
// channels' words are in `Decoded::words`, in the raster's channel order.
Decoded read_image(rust::Str path, uint64_t max_pixels);

}  // namespace oiio
}  // namespace rangewalk

#include "rangewalk/ffi/oiio.h"
#include "rangewalk/src/image/oiio.rs.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace rangewalk {
namespace oiio {

namespace {

[[noreturn]] void fail(const std::string &path, const std::string &what,
                       const std::string &detail) {
    std::string message = path + ": " + what;
    if (!detail.empty())
        message += ": " + detail;
    throw std::runtime_error(message);
}

// What an OS error number means for someone writing a file, with what to
// do where there is something to do: OpenImageIO itself only says "File
// output failed", which does not tell a full disk from a bad path.
std::string os_error(int err) {
    switch (err) {
    case ENOSPC:
        return "no space left on the device (the disk is full): free some space or "
               "write elsewhere";
    case EDQUOT:
        return "disk quota exceeded: free some space or write elsewhere";
    case EFBIG:
        return "file too large for this file system: write elsewhere";
    default:
        return std::strerror(err);
    }
}

// The file an image is written to, through its descriptor rather than
// stdio, so that the first OS error of a write (or of closing: some file
// systems only report a full disk then) is kept for the message.
// OpenImageIO's own IOFile keeps no errno, and through its buffered FILE
// a full disk may only show at fclose. Writes are unbuffered: OpenEXR
// hands over whole headers and compressed chunks (some 600 writes for a
// 512x512 range image, under 2 ms).
class FileOutput final : public OIIO::Filesystem::IOProxy {
public:
    explicit FileOutput(const std::string &path) : IOProxy(path, Write) {
        m_fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
        if (m_fd < 0) {
            m_errno = errno;
            m_mode = Closed;
        }
    }
    ~FileOutput() override { close(); }
    const char *proxytype() const override { return "rangewalk-file"; }
    void close() override {
        std::lock_guard<std::mutex> lock(m_mutex);
        if (m_fd >= 0 && ::close(m_fd) != 0 && m_errno == 0)
            m_errno = errno;
        m_fd = -1;
        m_mode = Closed;
    }
    bool seek(int64_t offset) override {
        m_pos = offset;
        return offset >= 0;
    }
    size_t write(const void *buf, size_t size) override {
        size_t n = pwrite(buf, size, m_pos);
        m_pos += int64_t(n);
        return n;
    }
    // OpenEXR may write from several threads; each write is whole here.
    size_t pwrite(const void *buf, size_t size, int64_t offset) override {
        std::lock_guard<std::mutex> lock(m_mutex);
        const char *p = static_cast<const char *>(buf);
        size_t done = 0;
        while (m_fd >= 0 && done < size) {
            ssize_t n = ::pwrite(m_fd, p + done, size - done, offset + int64_t(done));
            if (n < 0 && errno == EINTR)
                continue;
            if (n <= 0) {
                if (m_errno == 0)
                    m_errno = n < 0 ? errno : EIO;
                break;
            }
            done += size_t(n);
        }
        m_size = std::max(m_size, size_t(offset) + done);
        return done;
    }
    size_t size() const override { return m_size; }
    // The first OS error number, 0 if none.
    int error_number() {
        std::lock_guard<std::mutex> lock(m_mutex);
        return m_errno;
    }

private:
    int m_fd = -1;
    int m_errno = 0;
    size_t m_size = 0;
    std::mutex m_mutex;
};

// A writer and the file it writes: the writer refers to the file, so the
// file goes last.
struct Output {
    std::unique_ptr<FileOutput> file;
    std::unique_ptr<OIIO::ImageOutput> out;
};

// Creates a writer of the named format (not guessed from the file name, so
// temporary names need no particular extension) and opens `path` with
// `spec`, through a FileOutput where the format takes one.
Output open_output(const std::string &path, const char *format, const OIIO::ImageSpec &spec) {
    Output o;
    o.out = OIIO::ImageOutput::create(format);
    if (!o.out)
        fail(path, std::string("no ") + format + " writer", OIIO::geterror());
    if (o.out->supports("ioproxy")) {
        o.file = std::make_unique<FileOutput>(path);
        if (int err = o.file->error_number())
            fail(path, "cannot create", os_error(err));
        o.out->set_ioproxy(o.file.get());
    }
    if (!o.out->open(path, spec)) {
        int err = o.file ? o.file->error_number() : 0;
        fail(path, "cannot open for writing", err ? os_error(err) : o.out->geterror());
    }
    return o;
}

// Closes the writer and its file; fails naming the first OS error, where
// there was one, else what OpenImageIO says.
void finish(Output &o, const std::string &path, bool written) {
    std::string detail = written ? "" : o.out->geterror();
    bool closed = o.out->close();
    if (written && !closed)
        detail = o.out->geterror();
    int err = 0;
    if (o.file) {
        o.file->close();
        err = o.file->error_number();
    }
    const char *what = written ? "cannot finish writing" : "cannot write pixels";
    if (err)
        fail(path, what, os_error(err));
    if (!written || !closed)
        fail(path, what, detail);
}

void put_attribute(OIIO::ImageSpec &spec, const Attribute &a) {
    std::string name(a.name);
    if (a.floats.empty()) {
        spec.attribute(name, std::string(a.text));
    } else if (a.floats.size() == 3) {
        spec.attribute(name, OIIO::TypeVector, a.floats.data());
    } else if (a.floats.size() == 1) {
        spec.attribute(name, a.floats[0]);
    } else {
        spec.attribute(name, OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, int(a.floats.size())),
                       a.floats.data());
    }
}

Attribute get_attribute(const OIIO::ParamValue &p, bool &known) {
    Attribute a;
    a.name = std::string(p.name().string());
    OIIO::TypeDesc t = p.type();
    known = true;
    if (t.basetype == OIIO::TypeDesc::FLOAT) {
        const float *v = static_cast<const float *>(p.data());
        size_t n = size_t(p.nvalues()) * t.aggregate * std::max(1, t.arraylen);
        for (size_t i = 0; i < n; ++i)
            a.floats.push_back(v[i]);
    } else if (t == OIIO::TypeString) {
        a.text = std::string(p.get_string());
    } else {
        known = false;
    }
    return a;
}

}  // namespace

void write_image(rust::Str path_str, rust::Str format, const Raster &image) {
    std::string path(path_str);
    size_t n = size_t(image.width) * image.height;
    size_t nch = image.channels.size();
    if (nch == 0)
        fail(path, "an image needs at least one channel", "");
    OIIO::ImageSpec spec(int(image.width), int(image.height), int(nch), OIIO::TypeFloat);
    // The data window inside a display window whose corner is the origin.
    if (image.full_width > uint64_t(INT32_MAX) || image.full_height > uint64_t(INT32_MAX) ||
        image.x < INT32_MIN || image.x > INT32_MAX || image.y < INT32_MIN || image.y > INT32_MAX)
        fail(path, "window does not fit an image header", "");
    spec.x = int(image.x);
    spec.y = int(image.y);
    spec.full_x = 0;
    spec.full_y = 0;
    spec.full_width = int(image.full_width);
    spec.full_height = int(image.full_height);
    spec.channelnames.clear();
    for (const Channel &c : image.channels) {
        if (c.data.size() != n)
            fail(path, "channel " + std::string(c.name) + " has " + std::to_string(c.data.size()) +
                           " samples for " + std::to_string(n) + " pixels",
                 "");
        spec.channelnames.push_back(std::string(c.name));
        spec.channelformats.push_back(c.sample == Sample::U32 ? OIIO::TypeUInt32
                                                               : OIIO::TypeFloat);
    }
    for (const Attribute &a : image.attributes)
        put_attribute(spec, a);
    if (std::string(format) == "openexr") {
        spec.attribute("compression", "zip");
        // OpenImageIO stamps EXR files with the time of writing unless a
        // date is given; an empty one keeps the same pixels the same bytes,
        // which is what checksums of resumed and sharded bakes compare.
        if (!spec.find_attribute("DateTime"))
            spec.attribute("DateTime", "");
    }

    // Both sample types are four bytes, so the file's native pixel layout
    // is a plain interleave of the 32-bit words, made a strip of rows at a
    // time: the whole interleaved image would hold every channel twice
    // (over half a gigabyte for a 2,544-pixel sphere with its layers). 64
    // rows are whole blocks of every EXR compression.
    const size_t width = image.width, strip = 64;
    std::vector<uint32_t> pixels(std::min<size_t>(strip, image.height) * width * nch);
    Output out = open_output(path, std::string(format).c_str(), spec);
    bool ok = true;
    for (size_t y0 = 0; ok && y0 < image.height; y0 += strip) {
        size_t y1 = std::min<size_t>(y0 + strip, image.height);
        for (size_t c = 0; c < nch; ++c) {
            const uint32_t *data = image.channels[c].data.data() + y0 * width;
            for (size_t i = 0; i < (y1 - y0) * width; ++i)
                pixels[i * nch + c] = data[i];
        }
        ok = out.out->write_scanlines(spec.y + int(y0), spec.y + int(y1), 0, OIIO::TypeUnknown,
                                      pixels.data());
    }
    finish(out, path, ok);
}

void write_rgb8(rust::Str path_str, uint32_t width, uint32_t height,
                rust::Slice<const uint8_t> rgb) {
    std::string path(path_str);
    if (rgb.size() != size_t(width) * height * 3)
        fail(path, std::to_string(rgb.size()) + " bytes do not hold " + std::to_string(width) +
                       "x" + std::to_string(height) + " RGB pixels",
             "");
    OIIO::ImageSpec spec(int(width), int(height), 3, OIIO::TypeUInt8);
    Output out = open_output(path, "png", spec);
    bool ok = out.out->write_image(OIIO::TypeUInt8, rgb.data());
    finish(out, path, ok);
}

rust::Slice<const uint32_t> Words::channel(size_t c) const {
    if (c >= channels.size() || !channels[c])
        throw std::out_of_range("no channel " + std::to_string(c));
    return {channels[c].get(), pixels};
}

void Words::release(size_t c) {
    if (c < channels.size())
        channels[c].reset();
}

Decoded read_image(rust::Str path_str, uint64_t max_pixels) {
    std::string path(path_str);
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        fail(path, "cannot read image", OIIO::geterror());
    const OIIO::ImageSpec &spec = in->spec();
    if (spec.depth != 1)
        fail(path, "volume images are not supported", "");
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        fail(path, "image has no pixels", "");

    size_t width = size_t(spec.width), n = width * spec.height;
    // A header of a few bytes can declare any size: refuse what no image
    // here may hold before allocating for it.
    if (uint64_t(spec.width) * uint64_t(spec.height) > max_pixels)
        fail(path,
             "image of " + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                 " pixels, more than the " + std::to_string(max_pixels) +
                 " an image may hold here",
             "");
    size_t stride = spec.pixel_bytes(true);
    Decoded d;
    d.raster.width = uint32_t(spec.width);
    d.raster.height = uint32_t(spec.height);
    d.raster.x = int64_t(spec.x) - spec.full_x;
    d.raster.y = int64_t(spec.y) - spec.full_y;
    d.raster.full_width = uint64_t(std::max(spec.full_width, 0));
    d.raster.full_height = uint64_t(std::max(spec.full_height, 0));
    d.raster.integer_samples = !spec.format.is_floating_point();
    d.words = std::make_unique<Words>();
    d.words->pixels = n;
    std::vector<OIIO::TypeDesc> formats, targets;
    std::vector<size_t> offsets;
    size_t offset = 0;
    for (int c = 0; c < spec.nchannels; ++c) {
        OIIO::TypeDesc format = spec.channelformat(c);
        Channel ch;
        ch.name = std::string(spec.channel_name(c));
        ch.sample = format == OIIO::TypeUInt32 ? Sample::U32 : Sample::F32;
        d.raster.channels.push_back(std::move(ch));
        formats.push_back(format);
        targets.push_back(format == OIIO::TypeUInt32 ? OIIO::TypeUInt32 : OIIO::TypeFloat);
        offsets.push_back(offset);
        offset += format.size();
        // Not zeroed: pages are touched only as strips arrive, so a file
        // cut short costs no more memory than what it held.
        d.words->channels.emplace_back(new uint32_t[n]);
    }
    // A strip of rows at a time in the file's own layout, split into one
    // vector per channel: the whole interleaved image would double what
    // a read holds at its peak (half a gigabyte for a 2,544-pixel sphere).
    // 64 rows are whole blocks of every EXR compression. Tiled files are
    // read whole.
    const bool tiled = spec.tile_width != 0;
    const int strip = tiled ? spec.height : 64;
    std::unique_ptr<unsigned char[]> buffer(new unsigned char[size_t(strip) * width * stride]);
    unsigned char *native = buffer.get();
    for (int y0 = spec.y; y0 < spec.y + spec.height; y0 += strip) {
        int y1 = std::min(y0 + strip, spec.y + spec.height);
        size_t rows = size_t(y1 - y0), first = size_t(y0 - spec.y) * width;
        bool ok = tiled ? in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeUnknown, native)
                        : in->read_scanlines(0, 0, y0, y1, 0, 0, spec.nchannels,
                                             OIIO::TypeUnknown, native);
        if (!ok)
            fail(path, "cannot read pixels", in->geterror());
        for (int c = 0; c < spec.nchannels; ++c) {
            uint32_t *out = d.words->channels[c].get() + first;
            const unsigned char *px = native + offsets[c];
            if (formats[c] == targets[c]) {
                // Words stored as they are wanted: a plain strided copy
                // (convert_image would call memcpy once per pixel).
                for (size_t i = 0; i < rows * width; ++i, px += stride)
                    std::memcpy(out + i, px, sizeof(uint32_t));
            } else if (!OIIO::convert_image(1, spec.width, int(rows), 1, px, formats[c], stride,
                                            stride * width, OIIO::AutoStride, out, targets[c],
                                            sizeof(uint32_t), sizeof(uint32_t) * width,
                                            OIIO::AutoStride))
                fail(path,
                     "cannot convert channel " + std::string(spec.channel_name(c)) + " from " +
                         formats[c].c_str(),
                     "");
        }
    }
    for (const OIIO::ParamValue &p : spec.extra_attribs) {
        bool known = false;
        Attribute a = get_attribute(p, known);
        if (known)
            d.raster.attributes.push_back(std::move(a));
    }
    in->close();
    return d;
}

}  // namespace oiio
}  // namespace rangewalk

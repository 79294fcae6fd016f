#include "io/image_io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <system_error>
#include <utility>
#include <vector>

namespace tessera {

namespace {

namespace fs = std::filesystem;

[[noreturn]] void Fail(const std::string& what, const std::string& path,
                       const std::string& detail) {
    throw std::runtime_error(what + " " + path + ": " +
                             (detail.empty() ? "unknown error" : detail));
}

void CheckShape(const std::string& path, const Image& image) {
    size_t expected = static_cast<size_t>(std::max(image.width, 0)) * std::max(image.height, 0) *
                      image.channels.size();
    if (image.width <= 0 || image.height <= 0 || image.channels.empty() ||
        image.pixels.size() != expected)
        Fail("cannot write", path,
             "image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                 " with " + std::to_string(image.channels.size()) + " channels but holds " +
                 std::to_string(image.pixels.size()) + " values");
}

// A temporary file that is removed unless Keep() is called, so that whatever fails
// (OpenImageIO, the rename, an exception from anywhere) no half-written file stays behind.
class TemporaryFile {
  public:
    explicit TemporaryFile(std::string path) : path_(std::move(path)) {}
    TemporaryFile(const TemporaryFile&) = delete;
    TemporaryFile& operator=(const TemporaryFile&) = delete;
    ~TemporaryFile() {
        std::error_code ignored;
        if (!kept_) fs::remove(path_, ignored);
    }
    const std::string& Path() const { return path_; }
    void Keep() { kept_ = true; }

  private:
    std::string path_;
    bool kept_ = false;
};

// Writes `pixels` through OpenImageIO's `format` writer under a temporary name beside
// `path`, then renames it into place, so that readers (a farm's coordinator, a viewer
// polling the folder) never see a half-written file. The temporary name has no image
// extension, hence the explicit format.
void WriteAtomically(const std::string& path, const char* format, const OIIO::ImageSpec& spec,
                     OIIO::TypeDesc pixel_type, const void* pixels) {
    TemporaryFile temp(path + ".tmp-" + std::to_string(::getpid()));
    {
        // Declared after `temp`: on any failure the writer closes its file before the
        // temporary is removed.
        std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
        if (!out) Fail("cannot write", path, OIIO::geterror());
        if (!out->open(temp.Path(), spec)) Fail("cannot write", path, out->geterror());
        if (!out->write_image(pixel_type, pixels)) {
            std::string error = out->geterror();
            out->close();
            Fail("cannot write", path, error);
        }
        if (!out->close()) Fail("cannot write", path, out->geterror());
    }
    std::error_code ec;
    fs::rename(temp.Path(), path, ec);
    if (ec) Fail("cannot write", path, ec.message());
    temp.Keep();
}

struct FormatName {
    const char* extension;
    ImageFormat format;
};
constexpr FormatName kFormatNames[] = {
    {".exr", ImageFormat::kExr},   {".png", ImageFormat::kPng},  {".jpg", ImageFormat::kJpeg},
    {".jpeg", ImageFormat::kJpeg}, {".tif", ImageFormat::kTiff}, {".tiff", ImageFormat::kTiff},
    {".hdr", ImageFormat::kHdr},
};

// OpenImageIO's name for the writer of `format`.
const char* WriterName(ImageFormat format) {
    switch (format) {
        case ImageFormat::kExr:
            return "openexr";
        case ImageFormat::kPng:
            return "png";
        case ImageFormat::kJpeg:
            return "jpeg";
        case ImageFormat::kTiff:
            return "tiff";
        case ImageFormat::kHdr:
            return "hdr";
    }
    throw std::logic_error("unknown image format");
}

// The sRGB transfer curve (IEC 61966-2-1), linear part included.
float LinearToSrgb(float v) {
    return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

uint8_t ToSrgb8(float linear) {
    // NaN and negatives go to black: clamp's comparisons would let NaN through.
    float v = linear > 0 ? std::min(linear, 1.0f) : 0.0f;
    return static_cast<uint8_t>(std::lround(LinearToSrgb(v) * 255.0f));
}

// OpenImageIO's name for the reader of files with `path`'s extension, from its own table of
// extensions, so that no reader guesses the format from the content (which may mean
// trying every reader on it).
std::string ReaderForExtension(const std::string& path) {
    std::string extension = fs::path(path).extension().string();
    if (!extension.empty()) extension.erase(0, 1);
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (extension.empty()) Fail("cannot read", path, "the file name has no image extension");
    // "openexr:exr,sxr,mxr;png:png;..."
    const std::string table = OIIO::get_string_attribute("extension_list");
    size_t begin = 0;
    while (begin < table.size()) {
        size_t end = table.find(';', begin);
        if (end == std::string::npos) end = table.size();
        const std::string entry = table.substr(begin, end - begin);
        begin = end + 1;
        const size_t colon = entry.find(':');
        if (colon == std::string::npos) continue;
        std::string list = "," + entry.substr(colon + 1) + ",";
        if (list.find("," + extension + ",") != std::string::npos) return entry.substr(0, colon);
    }
    Fail("cannot read", path, "no image reader knows the extension '." + extension + "'");
}

// Stops a decode (OpenImageIO's progress callback: true aborts) once its time is up.
struct DecodeDeadline {
    std::chrono::steady_clock::time_point end;
    bool expired = false;

    static bool Check(void* opaque, float /*portion_done*/) {
        auto* self = static_cast<DecodeDeadline*>(opaque);
        if (std::chrono::steady_clock::now() >= self->end) self->expired = true;
        return self->expired;
    }
};

// The first subimage of the open `in`, as float, after checking its declared size.
Image ReadPixels(OIIO::ImageInput& in, const std::string& name, const ImageDecodeLimits& limits,
                 ImageMetadata* metadata) {
    const OIIO::ImageSpec& spec = in.spec();
    const std::string shape = std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                              (spec.depth > 1 ? "x" + std::to_string(spec.depth) : "") +
                              " pixels of " + std::to_string(spec.nchannels) + " channels";
    if (spec.width <= 0 || spec.height <= 0 || spec.depth <= 0 || spec.nchannels <= 0)
        Fail("cannot read", name, "the image declares " + shape);
    const uint64_t pixels = static_cast<uint64_t>(spec.width) * static_cast<uint64_t>(spec.height);
    if (spec.depth != 1 || pixels > limits.max_pixels || spec.nchannels > limits.max_channels)
        Fail("cannot read", name,
             "the image declares " + shape + ", over the limit of " +
                 std::to_string(limits.max_pixels) + " pixels (one layer) of at most " +
                 std::to_string(limits.max_channels) + " channels");
    if (pixels * static_cast<uint64_t>(spec.nchannels) * sizeof(float) > limits.max_decoded_bytes)
        Fail("cannot read", name,
             "the image declares " + shape + ", over the limit of " +
                 std::to_string(limits.max_decoded_bytes >> 20) + " MiB decoded");
    // Converting to float, OpenImageIO reads through a buffer of up to 256 native
    // scanlines, whatever the image's height: a very wide image (a header's width, for
    // 4 rows) would have it allocate 256 of them.
    constexpr uint64_t kBufferedScanlines = 256;
    if (static_cast<uint64_t>(spec.scanline_bytes(true)) * kBufferedScanlines >
        limits.max_decoded_bytes)
        Fail("cannot read", name,
             "the image declares " + shape + ": its scanlines of " +
                 std::to_string(spec.scanline_bytes(true)) + " bytes are over the limit of " +
                 std::to_string(limits.max_decoded_bytes / kBufferedScanlines) +
                 " bytes a decoder may buffer 256 of");
    Image image;
    image.width = spec.width;
    image.height = spec.height;
    image.channels.resize(spec.nchannels);
    for (int c = 0; c < spec.nchannels; ++c) image.channels[c] = spec.channel_name(c);
    image.pixels.resize(static_cast<size_t>(pixels) * spec.nchannels);
    DecodeDeadline deadline;
    const auto budget = std::chrono::duration<double>(limits.max_seconds);
    deadline.end =
        budget.count() >= 1e9
            ? std::chrono::steady_clock::time_point::max()
            : std::chrono::steady_clock::now() +
                  std::chrono::duration_cast<std::chrono::steady_clock::duration>(budget);
    const bool read = in.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT,
                                    image.pixels.data(), OIIO::AutoStride, OIIO::AutoStride,
                                    OIIO::AutoStride, &DecodeDeadline::Check, &deadline);
    if (deadline.expired) {
        char seconds[32];
        std::snprintf(seconds, sizeof(seconds), "%g", limits.max_seconds);
        Fail("cannot read", name, std::string("decoding took longer than ") + seconds + " s");
    }
    if (!read) Fail("cannot read", name, in.geterror());
    if (metadata != nullptr) {
        for (const OIIO::ParamValue& p : spec.extra_attribs)
            if (p.type() == OIIO::TypeDesc::STRING) (*metadata)[p.name().string()] = p.get_string();
    }
    in.close();
    return image;
}

}  // namespace

void WriteExr(const std::string& path, const Image& image, const ImageMetadata& metadata) {
    CheckShape(path, image);
    OIIO::ImageSpec spec(image.width, image.height, image.NumChannels(), OIIO::TypeDesc::FLOAT);
    spec.channelnames = image.channels;
    spec.alpha_channel = image.ChannelIndex("A");
    spec.z_channel = image.ChannelIndex("Z");
    spec.attribute("compression", "zip");
    for (const auto& [name, value] : metadata) spec.attribute(name, value);
    WriteAtomically(path, WriterName(ImageFormat::kExr), spec, OIIO::TypeDesc::FLOAT,
                    image.pixels.data());
}

std::optional<ImageFormat> FormatFromPath(const std::string& path) {
    std::string extension = fs::path(path).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    for (const FormatName& name : kFormatNames)
        if (extension == name.extension) return name.format;
    return std::nullopt;
}

std::string SupportedImageExtensions() {
    std::string list;
    for (const FormatName& name : kFormatNames)
        list += (list.empty() ? "" : ", ") + std::string(name.extension);
    return list;
}

void WriteRgbImage(const std::string& path, const Image& image, ImageFormat format) {
    if (format == ImageFormat::kExr) throw std::logic_error("WriteRgbImage writes no EXR: " + path);
    CheckShape(path, image);
    const int rgb[3] = {image.ChannelIndex("R"), image.ChannelIndex("G"), image.ChannelIndex("B")};
    if (rgb[0] < 0 || rgb[1] < 0 || rgb[2] < 0)
        Fail("cannot write", path, "image has no R, G and B channels");
    const size_t count = static_cast<size_t>(image.width) * image.height * 3;
    auto for_each_value = [&](auto&& store) {
        for (int y = 0; y < image.height; ++y)
            for (int x = 0; x < image.width; ++x)
                for (int c = 0; c < 3; ++c)
                    store((static_cast<size_t>(y) * image.width + x) * 3 + c,
                          image.At(x, y, rgb[c]));
    };
    // PNG and JPEG are display images (8-bit sRGB); TIFF and HDR keep linear float.
    if (format == ImageFormat::kPng || format == ImageFormat::kJpeg) {
        std::vector<uint8_t> pixels(count);
        for_each_value([&](size_t i, float v) { pixels[i] = ToSrgb8(v); });
        OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
        spec.attribute("oiio:ColorSpace", "sRGB");
        if (format == ImageFormat::kJpeg) spec.attribute("Compression", "jpeg:95");
        WriteAtomically(path, WriterName(format), spec, OIIO::TypeDesc::UINT8, pixels.data());
    } else {
        std::vector<float> pixels(count);
        for_each_value([&](size_t i, float v) { pixels[i] = v; });
        OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT);
        spec.attribute("oiio:ColorSpace", "linear");
        if (format == ImageFormat::kTiff) spec.attribute("compression", "zip");
        WriteAtomically(path, WriterName(format), spec, OIIO::TypeDesc::FLOAT, pixels.data());
    }
}

void WritePngPreview(const std::string& path, const Image& image) {
    WriteRgbImage(path, image, ImageFormat::kPng);
}

Image ReadImage(const std::string& path, ImageMetadata* metadata) {
    std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
    if (!in) Fail("cannot read", path, OIIO::geterror());
    ImageDecodeLimits unlimited;
    unlimited.max_pixels = UINT64_MAX;
    unlimited.max_channels = INT_MAX;
    unlimited.max_decoded_bytes = UINT64_MAX;
    unlimited.max_seconds = std::numeric_limits<double>::infinity();
    return ReadPixels(*in, path, unlimited, metadata);
}

// OpenEXR sizes its tables from the header before any pixel is read: a header of a few
// hundred bytes can make it allocate gigabytes and spend seconds inside open(). So an EXR
// header is walked here first, strictly: one part, scan lines or tiles (no deep data),
// well-formed attributes, and a data window within the pixel limit.
void CheckExrHeader(std::string_view bytes, const std::string& name,
                    const ImageDecodeLimits& limits) {
    auto bad = [&](const std::string& why) { Fail("cannot read", name, "bad EXR header: " + why); };
    size_t at = 0;
    auto u32 = [&]() {
        if (bytes.size() - at < 4) bad("truncated");
        uint32_t v = 0;
        for (int i = 0; i < 4; ++i) v |= uint32_t(uint8_t(bytes[at + i])) << (8 * i);
        at += 4;
        return v;
    };
    auto text = [&](size_t max) {
        const size_t end = bytes.find('\0', at);
        if (end == std::string_view::npos || end - at > max) bad("unterminated or long name");
        std::string_view t = bytes.substr(at, end - at);
        at = end + 1;
        return t;
    };
    if (u32() != 20000630u) bad("not an OpenEXR file");
    const uint32_t version = u32();
    if ((version & 0xff) != 2) bad("version " + std::to_string(version & 0xff));
    if (version & (0x800 | 0x1000)) bad("deep or multi-part images are not supported");
    bool channels = false, window = false;
    for (int count = 0;; ++count) {
        if (count > 1000) bad("too many attributes");
        const std::string_view attribute = text(255);
        if (attribute.empty()) break;
        const std::string_view type = text(255);
        if (type.empty()) bad("attribute '" + std::string(attribute) + "' has no type");
        const uint32_t size = u32();
        if (size > bytes.size() - at) bad("attribute '" + std::string(attribute) + "' overruns");
        if (attribute == "channels") {
            if (type != "chlist" || size > 64 * 1024) bad("bad channel list");
            channels = true;
        } else if (attribute == "dataWindow") {
            if (type != "box2i" || size != 16) bad("bad data window");
            const size_t start = at;
            const int64_t x0 = int32_t(u32()), y0 = int32_t(u32());
            const int64_t x1 = int32_t(u32()), y1 = int32_t(u32());
            at = start;
            const int64_t w = x1 - x0 + 1, h = y1 - y0 + 1;
            if (w <= 0 || h <= 0 || uint64_t(w) * uint64_t(h) > limits.max_pixels)
                bad("a data window of " + std::to_string(w) + "x" + std::to_string(h) +
                    " pixels, over the limit of " + std::to_string(limits.max_pixels));
            window = true;
        }
        at += size;
    }
    if (!channels || !window) bad("no channel list or data window");
}

// libpng allocates each ancillary chunk (text, profiles, metadata) at the size its
// header claims before reading it: a chunk that claims 2 GB in a file of a few hundred
// bytes allocates 2 GB inside open(). The chunk list is walked here first: every chunk
// must lie within the file, up to IEND.
void CheckPngChunks(std::string_view bytes, const std::string& name) {
    static constexpr char kSignature[] = "\x89PNG\r\n\x1a\n";
    if (bytes.size() < 8 || bytes.substr(0, 8) != std::string_view(kSignature, 8))
        return;  // not a PNG: libpng says so itself
    size_t at = 8;
    while (bytes.size() - at >= 8) {
        uint32_t length = 0;
        for (int i = 0; i < 4; ++i) length = length << 8 | uint8_t(bytes[at + i]);
        const std::string type(bytes.substr(at + 4, 4));
        const size_t remaining = bytes.size() - at - 8;
        if (length > 0x7fffffffu || size_t(length) + 4 > remaining) {
            std::string printable;
            for (char c : type) printable += std::isalnum(uint8_t(c)) ? c : '?';
            Fail("cannot read", name,
                 "bad PNG: chunk '" + printable + "' at byte " + std::to_string(at) + " claims " +
                     std::to_string(length) + " bytes, but the file has only " +
                     std::to_string(remaining < 4 ? 0 : remaining - 4) + " after its header");
        }
        at += 12 + size_t(length);
        if (type == "IEND") return;
    }
}

Image DecodeImage(std::string_view bytes, const std::string& name, const ImageDecodeLimits& limits,
                  ImageMetadata* metadata) {
    const std::string format = ReaderForExtension(name);
    if (format == "openexr") CheckExrHeader(bytes, name, limits);
    if (format == "png") CheckPngChunks(bytes, name);
    std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::create(format);
    if (!in) Fail("cannot read", name, OIIO::geterror());
    if (!in->supports("ioproxy"))
        Fail("cannot read", name,
             "images in the '" + format + "' format cannot be read from memory; use one of " +
                 SupportedImageExtensions());
    OIIO::Filesystem::IOMemReader memory(bytes.data(), bytes.size());
    if (!in->set_ioproxy(&memory)) Fail("cannot read", name, in->geterror());
    OIIO::ImageSpec spec;
    if (!in->open(name, spec)) Fail("cannot read", name, in->geterror());
    return ReadPixels(*in, name, limits, metadata);
}

}  // namespace tessera

#include "io/image_io.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <system_error>
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

// Writes `pixels` through OpenImageIO's `format` writer under a temporary name beside
// `path`, then renames it into place, so that readers (a farm's coordinator, a viewer
// polling the folder) never see a half-written file. The temporary name ends in neither
// .exr nor .png, hence the explicit format.
void WriteAtomically(const std::string& path, const char* format, const OIIO::ImageSpec& spec,
                     OIIO::TypeDesc pixel_type, const void* pixels) {
    const std::string temp = path + ".tmp-" + std::to_string(::getpid());
    auto fail = [&](const std::string& detail) {
        std::error_code ignored;
        fs::remove(temp, ignored);
        Fail("cannot write", path, detail);
    };
    {
        std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(format);
        if (!out) fail(OIIO::geterror());
        if (!out->open(temp, spec)) fail(out->geterror());
        if (!out->write_image(pixel_type, pixels)) {
            std::string error = out->geterror();
            out->close();
            fail(error);
        }
        if (!out->close()) fail(out->geterror());
    }
    std::error_code ec;
    fs::rename(temp, path, ec);
    if (ec) fail(ec.message());
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

}  // namespace

void WriteExr(const std::string& path, const Image& image, const ImageMetadata& metadata) {
    CheckShape(path, image);
    OIIO::ImageSpec spec(image.width, image.height, image.NumChannels(), OIIO::TypeDesc::FLOAT);
    spec.channelnames = image.channels;
    spec.alpha_channel = image.ChannelIndex("A");
    spec.z_channel = image.ChannelIndex("Z");
    spec.attribute("compression", "zip");
    for (const auto& [name, value] : metadata) spec.attribute(name, value);
    WriteAtomically(path, "openexr", spec, OIIO::TypeDesc::FLOAT, image.pixels.data());
}

void WritePngPreview(const std::string& path, const Image& image) {
    CheckShape(path, image);
    const int r = image.ChannelIndex("R"), g = image.ChannelIndex("G"), b = image.ChannelIndex("B");
    if (r < 0 || g < 0 || b < 0) Fail("cannot write", path, "image has no R, G and B channels");
    std::vector<uint8_t> rgb(static_cast<size_t>(image.width) * image.height * 3);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            uint8_t* out = &rgb[(static_cast<size_t>(y) * image.width + x) * 3];
            out[0] = ToSrgb8(image.At(x, y, r));
            out[1] = ToSrgb8(image.At(x, y, g));
            out[2] = ToSrgb8(image.At(x, y, b));
        }
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    WriteAtomically(path, "png", spec, OIIO::TypeDesc::UINT8, rgb.data());
}

Image ReadImage(const std::string& path, ImageMetadata* metadata) {
    std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path);
    if (!in) Fail("cannot read", path, OIIO::geterror());
    const OIIO::ImageSpec& spec = in->spec();
    Image image;
    image.width = spec.width;
    image.height = spec.height;
    image.channels.resize(spec.nchannels);
    for (int c = 0; c < spec.nchannels; ++c) image.channels[c] = spec.channel_name(c);
    image.pixels.resize(static_cast<size_t>(spec.width) * spec.height * spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data()))
        Fail("cannot read", path, in->geterror());
    if (metadata != nullptr) {
        for (const OIIO::ParamValue& p : spec.extra_attribs)
            if (p.type() == OIIO::TypeDesc::STRING) (*metadata)[p.name().string()] = p.get_string();
    }
    in->close();
    return image;
}

}  // namespace tessera

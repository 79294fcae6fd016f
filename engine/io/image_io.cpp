#include "io/image_io.h"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
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

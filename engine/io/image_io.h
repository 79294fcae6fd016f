#pragma once

// Image files through OpenImageIO. Only this module includes OpenImageIO headers.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "film/image.h"

namespace tessera {

// Extra header attributes written into the EXR (e.g. "tessera:spp" -> "64").
using ImageMetadata = std::map<std::string, std::string>;

// The file formats a render can be written as. Only kExr keeps every channel and the
// metadata; the others hold R, G, B alone.
enum class ImageFormat { kExr, kPng, kJpeg, kTiff, kHdr };

// The format that `path`'s extension names, case-insensitively: .exr, .png, .jpg, .jpeg,
// .tif, .tiff, .hdr. nullopt for any other extension or none.
std::optional<ImageFormat> FormatFromPath(const std::string& path);
// The extensions FormatFromPath knows, for messages: ".exr, .png, ...".
std::string SupportedImageExtensions();

// Writes a float (32-bit) EXR with all of the image's channels. The file appears
// atomically: written to a temporary name in the same folder, then renamed. Throws
// std::runtime_error with the path and OpenImageIO's message on failure.
void WriteExr(const std::string& path, const Image& image, const ImageMetadata& metadata);
// Writes the R, G, B channels as `format` (not kExr), atomically: 8-bit sRGB (clamped to
// [0,1]) for PNG and JPEG, linear float for TIFF and HDR.
void WriteRgbImage(const std::string& path, const Image& image, ImageFormat format);
// WriteRgbImage as an 8-bit sRGB PNG.
void WritePngPreview(const std::string& path, const Image& image);
// Reads any image OpenImageIO understands, as float, with its channel names. The order
// of channels is the file's, not necessarily the one written (OpenEXR sorts them by name;
// OpenImageIO then lists R G B A first): look channels up with Image::ChannelIndex.
// *metadata (if given) receives the string attributes of the header.
Image ReadImage(const std::string& path, ImageMetadata* metadata = nullptr);

// Bounds on decoding an image that someone else supplied (a job's bundle).
struct ImageDecodeLimits {
    // The most pixels (width x height x depth) and channels a header may declare; checked
    // before any pixel is decoded, since a file of a few bytes can declare a huge image.
    uint64_t max_pixels = uint64_t(1) << 26;
    int max_channels = 16;
    // And the most memory the decoded floats may take (pixels x channels x 4 bytes).
    uint64_t max_decoded_bytes = uint64_t(1) << 30;
    // Decoding stops with an error once it has taken longer than this.
    double max_seconds = 30;
};

// Decodes an image from the bytes of a file already read (io/file_bytes.h), as float
// like ReadImage. The format is the one `name`'s extension names (nothing is guessed from
// the content, and no file is opened); formats whose OpenImageIO reader cannot read from
// memory are refused. Throws std::runtime_error naming the image as `name`.
Image DecodeImage(std::string_view bytes, const std::string& name, const ImageDecodeLimits& limits,
                  ImageMetadata* metadata = nullptr);

}  // namespace tessera

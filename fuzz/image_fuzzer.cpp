// Fuzzes the image texture reader as a scene's "image" texture reads it: DecodeImage from
// the file's bytes through OpenImageIO with limits scaled down from the sandbox's (see
// FuzzLimits), then the texture built from it, then lookups. The first input byte picks
// the file's extension (OpenImageIO chooses its reader by it first), the rest is the file.
// Any std::exception is a rejected file (the scene builder reports it as a scene error);
// crashes, sanitizer reports, or an allocation past libFuzzer's limit (a header claiming a
// huge image) are bugs. Only Tessera's code is instrumented, so coverage guides the
// fuzzer through its own code and OpenImageIO's behaviour is seen only from outside.

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdint>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>

#include "fuzz_util.h"
#include "io/image_io.h"
#include "material/image_texture.h"

namespace {

constexpr const char* kExtensions[] = {".png", ".exr", ".hdr", ".jpg",
                                       ".tif", ".bmp", ".tga", ".gif"};

// The sandbox's defaults allow 1 GiB of decoded floats, and a decoder may buffer as much
// again: a few header bytes within those limits would take the process past libFuzzer's
// 2 GiB RSS limit (under AddressSanitizer) without any bug. The same checks at a sixteenth
// of the size keep every input that obeys them well under it, so an RSS or allocation
// report is again a limit that was not enforced.
tessera::ImageDecodeLimits FuzzLimits() {
    tessera::ImageDecodeLimits limits;
    limits.max_pixels = uint64_t(1) << 22;
    limits.max_decoded_bytes = uint64_t(1) << 26;
    return limits;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    tessera::fuzz::QuietLogs();
    // One thread per read: the fuzzer runs one input at a time, and thread pools started
    // for each small image cost more than the read.
    OIIO::attribute("threads", 1);
    OIIO::attribute("exr_threads", 1);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    tessera::fuzz::Input in(data, size);
    const uint8_t choice = in.U8();
    const char* ext = kExtensions[choice % std::size(kExtensions)];
    const bool srgb = choice & 0x80;
    const std::string bytes = in.Rest();
    try {
        auto texture = std::make_unique<tessera::ImageTexture>(
            tessera::DecodeImage(bytes, std::string("image") + ext, FuzzLimits()), srgb);
        const float max_value = texture->MaxValue();
        for (float u : {0.0f, 0.3f, 0.999f, -2.5f, 1e9f, NAN}) {
            tessera::TextureContext ctx;
            ctx.uv = {u, 1.0f - u};
            const tessera::Rgb v = texture->Evaluate(ctx);
            // A lookup blends texels, so it cannot exceed the largest (NaN texels aside).
            for (int c = 0; c < 3; ++c)
                if (v[c] > max_value * 1.0001f + 1e-6f && std::isfinite(max_value))
                    tessera::fuzz::Bug("image texture", "a lookup exceeds the texture's maximum");
        }
    } catch (const std::exception& e) {
        tessera::fuzz::Rejected(e);
    }
    return 0;
}

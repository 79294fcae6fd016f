#pragma once

// A float image with named channels, stored interleaved (pixel-major), rows top to bottom.

#include <string>
#include <vector>

namespace tessera {

struct Image {
    int width = 0, height = 0;
    std::vector<std::string> channels;  // e.g. R G B A albedo.R albedo.G albedo.B N.X N.Y N.Z Z
    std::vector<float> pixels;          // width * height * channels.size()

    int NumChannels() const { return static_cast<int>(channels.size()); }
    // Index of a channel by name, or -1.
    int ChannelIndex(const std::string& name) const;
    float& At(int x, int y, int c) {
        return pixels[(static_cast<size_t>(y) * width + x) * channels.size() + c];
    }
    float At(int x, int y, int c) const {
        return pixels[(static_cast<size_t>(y) * width + x) * channels.size() + c];
    }
};

}  // namespace tessera

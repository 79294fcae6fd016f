#include "film/image.h"

namespace tessera {

int Image::ChannelIndex(const std::string& name) const {
    for (size_t i = 0; i < channels.size(); ++i)
        if (channels[i] == name) return static_cast<int>(i);
    return -1;
}

}  // namespace tessera

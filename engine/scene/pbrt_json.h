#pragma once

// JSON text for the pbrt converter (scene/pbrt_import.h), which writes Tessera's scene
// description as text for the ordinary scene parser to read.

#include <set>
#include <string>

#include "core/color.h"
#include "scene/pbrt_math.h"

namespace tessera::pbrt {

// The shortest text that reads back as the same float (the scene parser keeps floats).
std::string Num(double v);

// A JSON string. Valid UTF-8 passes; any other byte becomes U+FFFD, so that the JSON text
// stays valid.
std::string Quote(const std::string& s);

// A key of a JSON pointer (RFC 6901).
std::string PointerKey(const std::string& s);

// `base`, or the first of "base #2", "base #3", ... not in `used`; added to `used`. Keys of
// a JSON object must differ.
std::string UniqueName(std::set<std::string>& used, const std::string& base);

// A JSON object written member by member.
class JsonMembers {
  public:
    JsonMembers& Add(const std::string& key, const std::string& json) {
        text_ += (text_.empty() ? "" : ", ") + Quote(key) + ": " + json;
        return *this;
    }
    std::string Str() const { return "{" + text_ + "}"; }

  private:
    std::string text_;
};

std::string JsonVec(const V3& v);
// A colour; a grey as one number.
std::string JsonRgb(const Rgb& c);
// {"matrix": [16 numbers, row by row]}.
std::string JsonMatrix(const M4& x);
// The rotation `q` (orthonormal, determinant 1) as Tessera's {"axis", "angle"}.
std::string JsonRotation(const M4& q);

}  // namespace tessera::pbrt

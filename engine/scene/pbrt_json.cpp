// JSON text for the pbrt converter (scene/pbrt_json.h).

#include "scene/pbrt_json.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace tessera::pbrt {

std::string Num(double v) {
    char buf[64];
    const float f = static_cast<float>(v);
    auto r = std::isfinite(f) ? std::to_chars(buf, buf + sizeof(buf), f)
                              : std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

std::string Quote(const std::string& s) {
    std::string out = "\"";
    for (size_t i = 0; i < s.size();) {
        const auto c = static_cast<unsigned char>(s[i]);
        if (c == '"' || c == '\\') {
            out += '\\';
            out += char(c);
            ++i;
        } else if (c < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", c);
            out += buf;
            ++i;
        } else if (c < 0x80) {
            out += char(c);
            ++i;
        } else {
            const int n = c >= 0xf0 && c < 0xf5 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 && c < 0xe0 ? 2 : 0;
            bool ok = n > 0 && i + size_t(n) <= s.size();
            for (int k = 1; ok && k < n; ++k)
                ok = (static_cast<unsigned char>(s[i + k]) & 0xc0) == 0x80;
            if (ok) {
                out.append(s, i, size_t(n));
                i += size_t(n);
            } else {
                out += "\xef\xbf\xbd";
                ++i;
            }
        }
    }
    return out + "\"";
}

std::string PointerKey(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
    return out;
}

std::string UniqueName(std::set<std::string>& used, const std::string& base) {
    std::string name = base;
    for (int i = 2; used.count(name); ++i) name = base + " #" + std::to_string(i);
    used.insert(name);
    return name;
}

std::string JsonVec(const V3& v) {
    return "[" + Num(v.x) + ", " + Num(v.y) + ", " + Num(v.z) + "]";
}

std::string JsonRgb(const Rgb& c) {
    if (c.r == c.g && c.g == c.b) return Num(c.r);
    return "[" + Num(c.r) + ", " + Num(c.g) + ", " + Num(c.b) + "]";
}

std::string JsonMatrix(const M4& x) {
    std::string s = "{\"matrix\": [";
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) s += (i || j ? ", " : "") + Num(x.m[i][j]);
    return s + "]}";
}

std::string JsonRotation(const M4& q) {
    const double trace = q.m[0][0] + q.m[1][1] + q.m[2][2];
    const double angle = std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0));
    V3 axis{q.m[2][1] - q.m[1][2], q.m[0][2] - q.m[2][0], q.m[1][0] - q.m[0][1]};
    if (angle > kPi - 1e-3) {
        // Near a half turn the antisymmetric part vanishes: q + 1 = 2 a a^T.
        const double xx = (q.m[0][0] + 1) / 2, yy = (q.m[1][1] + 1) / 2, zz = (q.m[2][2] + 1) / 2;
        if (xx >= yy && xx >= zz) {
            const double x = std::sqrt(std::max(xx, 0.0));
            axis = {x, (q.m[0][1] + q.m[1][0]) / (4 * x), (q.m[0][2] + q.m[2][0]) / (4 * x)};
        } else if (yy >= zz) {
            const double y = std::sqrt(std::max(yy, 0.0));
            axis = {(q.m[0][1] + q.m[1][0]) / (4 * y), y, (q.m[1][2] + q.m[2][1]) / (4 * y)};
        } else {
            const double z = std::sqrt(std::max(zz, 0.0));
            axis = {(q.m[0][2] + q.m[2][0]) / (4 * z), (q.m[1][2] + q.m[2][1]) / (4 * z), z};
        }
    }
    return JsonMembers()
        .Add("axis", JsonVec(Normalized(axis)))
        .Add("angle", Num(angle * 180 / kPi))
        .Str();
}

}  // namespace tessera::pbrt

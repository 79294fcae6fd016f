// Conversion of pbrt-v4 and pbrt-v3 scene files into Tessera's JSON scene description
// (scene/pbrt_import.h; the subset: docs/pbrt-import.md). In file order: JSON text and
// small math helpers, spectra, the tokenizer (comments, strings, brackets), typed parameter
// lists, and the converter, which keeps pbrt's graphics state and writes one JSON record per
// material, shape and light. Every parameter a conversion reads is marked used; the others
// are reported with their file and line, like pbrt's ReportUnused.
//
// One file rather than a tokenizer, a parameter and a converter file: the three share
// their types and are read together.

#include "scene/pbrt_import.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string_view>
#include <unordered_set>

#include "core/color.h"
#include "core/math.h"
#include "io/file_bytes.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

constexpr int kMaxIncludeDepth = 32;

// ---------------------------------------------------------------------------------------
// Places and JSON text

struct Loc {
    std::shared_ptr<const std::string> file;
    int line = 0;
    std::string Str() const {
        return (file ? *file : std::string("?")) + ":" + std::to_string(line);
    }
};

[[noreturn]] void SyntaxError(const Loc& loc, const std::string& what) {
    throw SceneError(loc.Str(), what);
}

// The shortest text that reads back as the same float (the scene parser keeps floats).
std::string Num(double v) {
    char buf[64];
    const float f = static_cast<float>(v);
    auto r = std::isfinite(f) ? std::to_chars(buf, buf + sizeof(buf), f)
                              : std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

// Valid UTF-8 passes; any other byte becomes U+FFFD, so that the JSON text stays valid.
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

// A key of a JSON pointer (RFC 6901).
std::string PointerKey(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
    return out;
}

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

// ---------------------------------------------------------------------------------------
// Math in double precision: pbrt's transforms compose many steps.

struct V3 {
    double x = 0, y = 0, z = 0;
    V3 operator+(const V3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    V3 operator-(const V3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    V3 operator*(double s) const { return {x * s, y * s, z * s}; }
};
double Dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 Cross(const V3& a, const V3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double Length(const V3& v) { return std::sqrt(Dot(v, v)); }
V3 Normalized(const V3& v) {
    const double l = Length(v);
    return l > 0 ? v * (1 / l) : v;
}
std::string JsonVec(const V3& v) {
    return "[" + Num(v.x) + ", " + Num(v.y) + ", " + Num(v.z) + "]";
}
std::string JsonRgb(const Rgb& c) {
    if (c.r == c.g && c.g == c.b) return Num(c.r);
    return "[" + Num(c.r) + ", " + Num(c.g) + ", " + Num(c.b) + "]";
}

struct M4 {
    std::array<std::array<double, 4>, 4> m{};
    static M4 Identity() {
        M4 r;
        for (int i = 0; i < 4; ++i) r.m[i][i] = 1;
        return r;
    }
    M4 operator*(const M4& o) const {
        M4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j)
                for (int k = 0; k < 4; ++k) r.m[i][j] += m[i][k] * o.m[k][j];
        return r;
    }
    V3 Point(const V3& p) const {
        return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
    }
    V3 Vector(const V3& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    V3 Column(int j) const { return {m[0][j], m[1][j], m[2][j]}; }
    double Det3() const { return Dot(Column(0), Cross(Column(1), Column(2))); }
    bool IsAffine() const { return m[3][0] == 0 && m[3][1] == 0 && m[3][2] == 0 && m[3][3] == 1; }
    bool IsIdentity() const { return m == Identity().m; }
};

// Gauss-Jordan elimination with partial pivoting; false when singular.
bool Invert(const M4& a, M4* out) {
    M4 l = a, r = M4::Identity();
    for (int c = 0; c < 4; ++c) {
        int pivot = c;
        for (int i = c + 1; i < 4; ++i)
            if (std::abs(l.m[i][c]) > std::abs(l.m[pivot][c])) pivot = i;
        if (std::abs(l.m[pivot][c]) < 1e-300) return false;
        std::swap(l.m[c], l.m[pivot]);
        std::swap(r.m[c], r.m[pivot]);
        const double inv = 1 / l.m[c][c];
        for (int j = 0; j < 4; ++j) {
            l.m[c][j] *= inv;
            r.m[c][j] *= inv;
        }
        for (int i = 0; i < 4; ++i) {
            if (i == c) continue;
            const double f = l.m[i][c];
            for (int j = 0; j < 4; ++j) {
                l.m[i][j] -= f * l.m[c][j];
                r.m[i][j] -= f * r.m[c][j];
            }
        }
    }
    *out = r;
    return true;
}

M4 TranslateM(const V3& d) {
    M4 r = M4::Identity();
    r.m[0][3] = d.x;
    r.m[1][3] = d.y;
    r.m[2][3] = d.z;
    return r;
}

M4 ScaleM(const V3& s) {
    M4 r = M4::Identity();
    r.m[0][0] = s.x;
    r.m[1][1] = s.y;
    r.m[2][2] = s.z;
    return r;
}

// Right-handed rotation about a unit axis (pbrt's and Tessera's Rotate).
M4 RotateM(double degrees, const V3& a) {
    const double t = degrees * kPi / 180, s = std::sin(t), c = std::cos(t);
    M4 r = M4::Identity();
    r.m[0][0] = a.x * a.x + (1 - a.x * a.x) * c;
    r.m[0][1] = a.x * a.y * (1 - c) - a.z * s;
    r.m[0][2] = a.x * a.z * (1 - c) + a.y * s;
    r.m[1][0] = a.x * a.y * (1 - c) + a.z * s;
    r.m[1][1] = a.y * a.y + (1 - a.y * a.y) * c;
    r.m[1][2] = a.y * a.z * (1 - c) - a.x * s;
    r.m[2][0] = a.x * a.z * (1 - c) - a.y * s;
    r.m[2][1] = a.y * a.z * (1 - c) + a.x * s;
    r.m[2][2] = a.z * a.z + (1 - a.z * a.z) * c;
    return r;
}

std::string JsonMatrix(const M4& x) {
    std::string s = "{\"matrix\": [";
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) s += (i || j ? ", " : "") + Num(x.m[i][j]);
    return s + "]}";
}

// The rotation `q` (orthonormal, determinant 1) as Tessera's {"axis", "angle"}.
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

// ---------------------------------------------------------------------------------------
// Spectra as RGB

// The CIE 1931 colour-matching functions in the multi-lobe Gaussian fit of Wyman, Sloan
// and Shirley (2013), close enough for turning smooth spectra into RGB.
double Lobe(double nm, double mu, double s1, double s2) {
    const double t = (nm - mu) / (nm < mu ? s1 : s2);
    return std::exp(-0.5 * t * t);
}

V3 ColourMatch(double nm) {
    return {1.056 * Lobe(nm, 599.8, 37.9, 31.0) + 0.362 * Lobe(nm, 442.0, 16.0, 26.7) -
                0.065 * Lobe(nm, 501.1, 20.4, 26.2),
            0.821 * Lobe(nm, 568.8, 46.9, 40.5) + 0.286 * Lobe(nm, 530.9, 16.3, 31.1),
            1.217 * Lobe(nm, 437.0, 11.8, 36.0) + 0.681 * Lobe(nm, 459.0, 26.0, 13.8)};
}

V3 XyzToLinearSrgb(const V3& c) {
    return {3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z,
            -0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z,
            0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z};
}

using SpectrumFn = std::function<double(double nm)>;

V3 SpectrumXyz(const SpectrumFn& s) {
    V3 xyz;
    for (double nm = 360; nm <= 830; nm += 1) xyz = xyz + ColourMatch(nm) * s(nm);
    return xyz;
}

Rgb ClampedRgb(const V3& c) {
    return Rgb(float(std::max(c.x, 0.0)), float(std::max(c.y, 0.0)), float(std::max(c.z, 0.0)));
}

// Planck's law up to a constant factor (wavelength in nm).
double Planck(double nm, double kelvin) {
    if (!(kelvin > 0)) return 0;
    const double l = nm * 1e-9, c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
    return 1e-30 / (std::pow(l, 5) * (std::exp(h * c / (l * kb * kelvin)) - 1));
}

// An emitted spectrum as linear sRGB of luminance 1: pbrt-v4 divides every light's
// spectrum by its photometric value, so that only its colour remains.
Rgb IlluminantRgb(const SpectrumFn& s) {
    const V3 xyz = SpectrumXyz(s);
    if (!(xyz.y > 0)) return Rgb(0);
    return ClampedRgb(XyzToLinearSrgb(xyz * (1 / xyz.y)));
}

Rgb BlackbodyRgb(double kelvin) {
    return IlluminantRgb([kelvin](double nm) { return Planck(nm, kelvin); });
}

// A reflectance spectrum as linear sRGB: lit by D65 (here a 6504 K black body) and divided
// by that light's own RGB, so that a reflectance of 1 everywhere is white.
Rgb AlbedoRgb(const SpectrumFn& s) {
    const SpectrumFn d65 = [](double nm) { return Planck(nm, 6504); };
    const V3 white = XyzToLinearSrgb(SpectrumXyz(d65));
    const V3 lit = XyzToLinearSrgb(SpectrumXyz([&](double nm) { return s(nm) * d65(nm); }));
    return ClampedRgb({lit.x / white.x, lit.y / white.y, lit.z / white.z});
}

// A spectrum given as (wavelength, value) pairs, linear in between, constant beyond.
SpectrumFn PiecewiseLinear(const std::vector<double>& pairs) {
    std::vector<std::pair<double, double>> p;
    for (size_t i = 0; i + 1 < pairs.size(); i += 2) p.emplace_back(pairs[i], pairs[i + 1]);
    std::sort(p.begin(), p.end());
    return [p](double nm) {
        if (nm <= p.front().first) return p.front().second;
        if (nm >= p.back().first) return p.back().second;
        auto hi = std::lower_bound(p.begin(), p.end(), std::make_pair(nm, -1e300));
        auto lo = hi - 1;
        const double t = (nm - lo->first) / (hi->first - lo->first);
        return lo->second + t * (hi->second - lo->second);
    };
}

// Refractive indices at the d line (587.6 nm) of the glasses pbrt-v4 names.
struct NamedGlass {
    const char* name;
    double eta;
};
constexpr NamedGlass kGlasses[] = {{"glass-BK7", 1.5168},   {"glass-BAF10", 1.6700},
                                   {"glass-FK51A", 1.4866}, {"glass-LASF9", 1.8503},
                                   {"glass-F5", 1.6727},    {"glass-F10", 1.7283},
                                   {"glass-F11", 1.7847}};

// The metals Tessera names (docs/scene-format.md, "metal").
const std::set<std::string> kTesseraMetals = {"Ag", "Al", "Au", "Cr", "Cu"};

// The metal and quantity ("eta" or "k") a named spectrum or pbrt-v3 .spd file stands for:
// "metal-Au-eta", "spds/metals/Au.k.spd".
std::optional<std::pair<std::string, std::string>> MetalSpectrum(const std::string& name) {
    if (name.rfind("metal-", 0) == 0) {
        const size_t dash = name.rfind('-');
        if (dash > 6) return std::make_pair(name.substr(6, dash - 6), name.substr(dash + 1));
    }
    const std::string base = fs::path(name).filename().string();
    const size_t dot = base.find('.');
    if (base.size() > 4 && base.compare(base.size() - 4, 4, ".spd") == 0 &&
        dot != std::string::npos) {
        const std::string rest = base.substr(dot + 1, base.size() - 4 - dot - 1);
        if (rest == "eta" || rest == "k") return std::make_pair(base.substr(0, dot), rest);
    }
    return std::nullopt;
}

// ---------------------------------------------------------------------------------------
// Tokens

struct Token {
    std::string text;  // a string's contents, without quotes, escapes resolved
    bool quoted = false;
    Loc loc;
    bool Is(std::string_view s) const { return !quoted && text == s; }
};

// A bare word that starts a directive (numbers, brackets and booleans do not).
bool IsDirectiveName(const Token& t) {
    return !t.quoted && !t.text.empty() && std::isalpha(static_cast<unsigned char>(t.text[0])) &&
           t.text != "true" && t.text != "false";
}

class Tokenizer {
  public:
    Tokenizer(std::shared_ptr<const std::string> file, std::string text)
        : file_(std::move(file)), text_(std::move(text)) {}

    std::optional<Token> Next() {
        while (pos_ < text_.size()) {
            const char c = text_[pos_];
            if (c == '\n') {
                ++line_;
                ++pos_;
            } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
                ++pos_;
            } else if (c == '#') {
                while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
            } else {
                Token t;
                t.loc = {file_, line_};
                if (c == '[' || c == ']') {
                    t.text = std::string(1, c);
                    ++pos_;
                } else if (c == '"') {
                    t.quoted = true;
                    t.text = ReadString(t.loc);
                } else {
                    const size_t start = pos_;
                    while (pos_ < text_.size() && !IsDelimiter(text_[pos_])) ++pos_;
                    t.text = text_.substr(start, pos_ - start);
                }
                return t;
            }
        }
        return std::nullopt;
    }

  private:
    static bool IsDelimiter(char c) {
        return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v' ||
               c == '[' || c == ']' || c == '"' || c == '#';
    }

    std::string ReadString(const Loc& loc) {
        std::string s;
        for (++pos_;;) {
            if (pos_ >= text_.size()) SyntaxError(loc, "unterminated string");
            const char c = text_[pos_++];
            if (c == '"') return s;
            if (c == '\n') SyntaxError(loc, "unterminated string (a string ends on its line)");
            if (c != '\\') {
                s += c;
                continue;
            }
            if (pos_ >= text_.size()) SyntaxError(loc, "unterminated string");
            const char e = text_[pos_++];
            switch (e) {
                case 'b':
                    s += '\b';
                    break;
                case 'f':
                    s += '\f';
                    break;
                case 'n':
                    s += '\n';
                    break;
                case 'r':
                    s += '\r';
                    break;
                case 't':
                    s += '\t';
                    break;
                case '\\':
                case '\'':
                case '"':
                    s += e;
                    break;
                default:
                    SyntaxError(loc, std::string("unknown escape '\\") + e + "' in a string");
            }
        }
    }

    std::shared_ptr<const std::string> file_;
    std::string text_;
    size_t pos_ = 0;
    int line_ = 1;
};

// The tokens of a file and the files it includes, in reading order.
class TokenStream {
  public:
    void Push(Tokenizer t) { files_.push_back(std::move(t)); }
    size_t Depth() const { return files_.size(); }

    const Token* Peek() {
        while (!ahead_ && !files_.empty()) {
            ahead_ = files_.back().Next();
            if (!ahead_) files_.pop_back();
        }
        return ahead_ ? &*ahead_ : nullptr;
    }
    // The next token; at the end of the input, a syntax error at `from` saying `expected`.
    Token Next(const Loc& from, const std::string& expected) {
        if (!Peek()) SyntaxError(from, "unexpected end of file: expected " + expected);
        Token t = std::move(*ahead_);
        ahead_.reset();
        return t;
    }

  private:
    std::vector<Tokenizer> files_;
    std::optional<Token> ahead_;
};

// ---------------------------------------------------------------------------------------
// Parameter lists: "type name" value or [ values ]

struct Param {
    std::string type, name;
    Loc loc;
    std::vector<double> numbers;
    std::vector<std::string> strings;
    std::vector<bool> bools;
    bool used = false;
};

class ParamSet {
  public:
    std::vector<Param> params;

    // The last parameter `name` of one of `types`, marked used with every other of that
    // name and those types; nullptr if none.
    Param* Get(const std::string& name, std::initializer_list<std::string_view> types) {
        Param* found = nullptr;
        for (Param& p : params) {
            if (p.name != name) continue;
            if (std::find(types.begin(), types.end(), p.type) == types.end()) continue;
            p.used = true;
            found = &p;
        }
        return found;
    }
    bool Has(const std::string& name) const {
        return std::any_of(params.begin(), params.end(),
                           [&](const Param& p) { return p.name == name; });
    }
    double Float(const std::string& name, double def) {
        Param* p = Get(name, {"float"});
        return p && !p->numbers.empty() ? p->numbers[0] : def;
    }
    int Int(const std::string& name, int def) {
        Param* p = Get(name, {"integer"});
        return p && !p->numbers.empty() ? int(std::clamp(p->numbers[0], -2e9, 2e9)) : def;
    }
    bool Bool(const std::string& name, bool def) {
        Param* p = Get(name, {"bool"});
        return p && !p->bools.empty() ? p->bools[0] : def;
    }
    std::string String(const std::string& name, const std::string& def = "") {
        Param* p = Get(name, {"string"});
        return p && !p->strings.empty() ? p->strings[0] : def;
    }
    const std::vector<double>* Numbers(const std::string& name,
                                       std::initializer_list<std::string_view> types) {
        Param* p = Get(name, types);
        return p ? &p->numbers : nullptr;
    }
    V3 Point(const std::string& name, const V3& def) {
        const std::vector<double>* v = Numbers(name, {"point3"});
        return v && v->size() >= 3 ? V3{(*v)[0], (*v)[1], (*v)[2]} : def;
    }
    void MarkAllUsed() {
        for (Param& p : params) p.used = true;
    }
};

// pbrt-v3's type names as pbrt-v4's.
std::string CanonicalType(const std::string& t) {
    if (t == "point") return "point3";
    if (t == "vector") return "vector3";
    if (t == "normal") return "normal3";
    if (t == "color") return "rgb";
    return t;
}

bool ParseNumber(const std::string& s, double* out) {
    const char* b = s.data();
    const char* e = b + s.size();
    if (b != e && *b == '+') ++b;
    auto r = std::from_chars(b, e, *out);
    return r.ec == std::errc() && r.ptr == e && std::isfinite(*out);
}

// One parameter's declaration and values, checked against its type.
Param ReadParam(TokenStream& in, const Token& decl) {
    Param p;
    p.loc = decl.loc;
    {
        std::vector<std::string> words;
        size_t i = 0;
        while (i < decl.text.size()) {
            while (i < decl.text.size() && std::isspace(static_cast<unsigned char>(decl.text[i])))
                ++i;
            const size_t start = i;
            while (i < decl.text.size() && !std::isspace(static_cast<unsigned char>(decl.text[i])))
                ++i;
            if (i > start) words.push_back(decl.text.substr(start, i - start));
        }
        if (words.size() != 2)
            SyntaxError(decl.loc, "expected a parameter declaration \"type name\", got \"" +
                                      decl.text + "\"");
        p.type = CanonicalType(words[0]);
        p.name = words[1];
    }
    static const std::set<std::string> kTypes = {
        "integer", "float", "point2",   "vector2",   "point3", "vector3", "normal3",
        "rgb",     "xyz",   "spectrum", "blackbody", "bool",   "string",  "texture"};
    if (!kTypes.count(p.type))
        SyntaxError(decl.loc, "unknown parameter type '" + p.type + "' in \"" + decl.text + "\"");
    const std::string shown = "parameter \"" + decl.text + "\"";

    std::vector<Token> values;
    const Token* t = in.Peek();
    if (!t || IsDirectiveName(*t) || t->Is("]")) SyntaxError(decl.loc, shown + " has no value");
    if (t->Is("[")) {
        const Token open = in.Next(decl.loc, "values");
        for (;;) {
            const Token* v = in.Peek();
            if (!v) SyntaxError(open.loc, "'[' is never closed");
            if (v->Is("]")) break;
            if (v->Is("[") || IsDirectiveName(*v))
                SyntaxError(open.loc, "'[' is never closed (found '" + v->text + "' at line " +
                                          std::to_string(v->loc.line) + ")");
            values.push_back(in.Next(open.loc, "']'"));
        }
        in.Next(open.loc, "']'");
    } else {
        values.push_back(in.Next(decl.loc, "a value"));
    }

    if (p.type == "bool") {
        for (const Token& v : values) {
            if (v.text != "true" && v.text != "false")
                SyntaxError(v.loc, shown + ": expected true or false, got '" + v.text + "'");
            p.bools.push_back(v.text == "true");
        }
        return p;
    }
    const bool all_strings =
        std::all_of(values.begin(), values.end(), [](const Token& v) { return v.quoted; });
    if (p.type == "string" || p.type == "texture" || (p.type == "spectrum" && all_strings)) {
        if (!all_strings) SyntaxError(decl.loc, shown + ": expected quoted strings");
        for (const Token& v : values) p.strings.push_back(v.text);
        if (p.type == "spectrum" && p.strings.size() != 1)
            SyntaxError(decl.loc, shown + ": expected one spectrum name or file");
        return p;
    }
    for (const Token& v : values) {
        double x;
        if (v.quoted || !ParseNumber(v.text, &x))
            SyntaxError(v.loc, shown + ": expected a number, got '" + v.text + "'");
        p.numbers.push_back(x);
    }
    const size_t n = p.numbers.size();
    size_t arity = 1;
    if (p.type == "point2" || p.type == "vector2") arity = 2;
    if (p.type == "point3" || p.type == "vector3" || p.type == "normal3" || p.type == "rgb" ||
        p.type == "xyz")
        arity = 3;
    if (n % arity != 0)
        SyntaxError(decl.loc, shown + ": " + std::to_string(n) + " numbers, not a multiple of " +
                                  std::to_string(arity));
    if (p.type == "spectrum" && n != 1 && n % 2 != 0)
        SyntaxError(decl.loc, shown + ": expected (wavelength, value) pairs");
    if (p.type == "integer")
        for (double x : p.numbers)
            if (x != std::floor(x)) SyntaxError(decl.loc, shown + ": expected integers");
    return p;
}

ParamSet ReadParams(TokenStream& in) {
    ParamSet ps;
    while (const Token* t = in.Peek()) {
        if (!t->quoted) break;
        const Token decl = in.Next(Loc{}, "a parameter");
        ps.params.push_back(ReadParam(in, decl));
    }
    return ps;
}

// ---------------------------------------------------------------------------------------
// The converter

enum class SpectrumKind { kIlluminant, kAlbedo, kUnbounded };

struct AreaLight {
    Rgb radiance;
    bool two_sided = false;
};

// pbrt's graphics state, saved by AttributeBegin.
struct GraphicsState {
    M4 ctm = M4::Identity();
    bool reverse_orientation = false;
    std::string material;  // JSON name; empty: pbrt's default material
    bool surface = true;   // false: "interface" or "none", shapes without a surface
    std::optional<AreaLight> area_light;
};

// A texture as the converter can use it.
struct SpectrumTexture {
    std::optional<Rgb> constant;
    std::string json_name;  // an image texture in the "textures" section
};

struct SphereDef {
    M4 ctm;
    double radius = 1;
    std::string material;
    Loc loc;
};

struct ObjectDef {
    std::string json_name;
    std::vector<std::string> shapes;  // JSON, in object space
    std::vector<Loc> shape_locs;
    std::vector<SphereDef> spheres;  // Tessera's objects hold meshes only
};

class Converter {
  public:
    Converter(const std::string& shown, const PbrtIncludeReader& read)
        : shown_(shown), read_include_(read) {}

    PbrtImport Run(const std::string& text) {
        in_.Push(Tokenizer(std::make_shared<const std::string>(shown_), text));
        while (in_.Peek()) {
            const Token d = in_.Next(Loc{}, "a directive");
            if (!IsDirectiveName(d))
                SyntaxError(d.loc,
                            "expected a directive, got " +
                                (d.quoted ? "the string \"" + d.text + "\"" : "'" + d.text + "'"));
            Directive(d);
        }
        return Finish();
    }

  private:
    // --- reporting

    void Warn(const Loc& loc, const std::string& what) {
        auto [it, fresh] = warning_index_.emplace(what, warnings_.size());
        if (fresh)
            warnings_.push_back({loc.Str(), what, 0});
        else
            ++warnings_[it->second].more;
    }

    void ReportUnused(ParamSet& ps, const std::string& directive) {
        for (const Param& p : ps.params)
            if (!p.used)
                Warn(p.loc, directive + ": parameter \"" + p.type + " " + p.name +
                                "\" is not supported; ignored");
    }

    // --- positional arguments

    double NumberArg(const Token& d) {
        const Token t = in_.Next(d.loc, "a number after " + d.text);
        double x;
        if (t.quoted || !ParseNumber(t.text, &x))
            SyntaxError(t.loc, d.text + ": expected a number, got '" + t.text + "'");
        return x;
    }

    // n numbers, bare or in brackets.
    std::vector<double> NumberArgs(const Token& d, size_t n) {
        const Token* t = in_.Peek();
        const bool bracket = t && t->Is("[");
        if (bracket) in_.Next(d.loc, "'['");
        std::vector<double> v;
        for (size_t i = 0; i < n; ++i) v.push_back(NumberArg(d));
        if (bracket) {
            const Token close = in_.Next(d.loc, "']'");
            if (!close.Is("]"))
                SyntaxError(close.loc, d.text + ": expected ']' after " + std::to_string(n) +
                                           " numbers, got '" + close.text + "'");
        }
        return v;
    }

    std::string StringArg(const Token& d) {
        const Token t = in_.Next(d.loc, "a string after " + d.text);
        if (!t.quoted)
            SyntaxError(t.loc, d.text + ": expected a quoted string, got '" + t.text + "'");
        return t.text;
    }

    // --- directives

    void Directive(const Token& d) {
        const std::string& n = d.text;
        if (n == "Identity") {
            ApplyTransform(M4::Identity(), true);
        } else if (n == "Translate") {
            const std::vector<double> v = NumberArgs(d, 3);
            ApplyTransform(TranslateM({v[0], v[1], v[2]}));
        } else if (n == "Scale") {
            const std::vector<double> v = NumberArgs(d, 3);
            ApplyTransform(ScaleM({v[0], v[1], v[2]}));
        } else if (n == "Rotate") {
            const std::vector<double> v = NumberArgs(d, 4);
            const V3 axis{v[1], v[2], v[3]};
            if (Length(axis) == 0) return Warn(d.loc, "Rotate about a zero axis; skipped");
            ApplyTransform(RotateM(v[0], Normalized(axis)));
        } else if (n == "LookAt") {
            LookAt(d, NumberArgs(d, 9));
        } else if (n == "Transform" || n == "ConcatTransform") {
            const std::vector<double> v = NumberArgs(d, 16);
            M4 m;  // pbrt lists the matrix column by column
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) m.m[i][j] = v[size_t(j * 4 + i)];
            ApplyTransform(m, n == "Transform");
        } else if (n == "CoordinateSystem") {
            named_coordinates_[StringArg(d)] = state_.ctm;
        } else if (n == "CoordSysTransform") {
            const std::string name = StringArg(d);
            auto it = named_coordinates_.find(name);
            if (it == named_coordinates_.end())
                return Warn(d.loc, "CoordSysTransform: unknown coordinate system '" + name + "'");
            ApplyTransform(it->second, true);
        } else if (n == "ActiveTransform") {
            const Token t = in_.Next(d.loc, "StartTime, EndTime or All");
            if (t.Is("StartTime") || t.Is("All")) {
                transforms_active_ = true;
            } else if (t.Is("EndTime")) {
                transforms_active_ = false;
                Warn(d.loc,
                     "ActiveTransform EndTime: motion blur is not converted; transforms "
                     "of the shutter's end are ignored");
            } else {
                SyntaxError(t.loc, "ActiveTransform: expected StartTime, EndTime or All, got '" +
                                       t.text + "'");
            }
        } else if (n == "TransformTimes") {
            NumberArgs(d, 2);
            Warn(d.loc, "TransformTimes: motion blur is not converted; ignored");
        } else if (n == "ReverseOrientation") {
            state_.reverse_orientation = !state_.reverse_orientation;
        } else if (n == "AttributeBegin") {
            stack_.push_back({state_, false, d.loc});
        } else if (n == "TransformBegin") {
            stack_.push_back({state_, true, d.loc});
        } else if (n == "AttributeEnd" || n == "TransformEnd") {
            PopState(d);
        } else if (n == "WorldBegin") {
            WorldBegin(d);
        } else if (n == "WorldEnd") {
            // pbrt-v3 ends the scene here; anything after it is read all the same.
        } else if (n == "Include" || n == "Import") {
            Include(d, StringArg(d));
        } else if (n == "ObjectBegin") {
            ObjectBegin(d, StringArg(d));
        } else if (n == "ObjectEnd") {
            ObjectEnd(d);
        } else if (n == "ObjectInstance") {
            ObjectInstance(d, StringArg(d));
        } else if (n == "NamedMaterial") {
            const std::string name = StringArg(d);
            auto it = named_materials_.find(name);
            if (it == named_materials_.end()) {
                Warn(d.loc, "NamedMaterial: unknown material '" + name + "'; pbrt's default used");
                state_.material.clear();
                state_.surface = true;
            } else {
                state_.material = it->second.first;
                state_.surface = it->second.second;
            }
        } else if (n == "MediumInterface") {
            StringArg(d);
            if (const Token* t = in_.Peek(); t && t->quoted) StringArg(d);
            Warn(d.loc, "MediumInterface: participating media are not supported; ignored");
        } else if (n == "ColorSpace") {
            const std::string space = StringArg(d);
            if (space != "srgb")
                Warn(d.loc, "ColorSpace \"" + space + "\": colours are read as linear sRGB");
        } else if (n == "Option") {
            ParamSet ps = ReadParams(in_);
            for (const Param& p : ps.params)
                Warn(p.loc, "Option \"" + p.name + "\" is not supported; ignored");
        } else {
            DirectiveWithParams(d);
        }
    }

    // The directives that take a type (or name) and a parameter list.
    void DirectiveWithParams(const Token& d) {
        const std::string& n = d.text;
        static const std::set<std::string> kKnown = {
            "Camera",          "Sampler",         "Film",     "PixelFilter",
            "Integrator",      "Accelerator",     "Material", "Texture",
            "LightSource",     "AreaLightSource", "Shape",    "MakeNamedMaterial",
            "MakeNamedMedium", "Attribute"};
        if (!kKnown.count(n)) {
            Warn(d.loc, "unknown directive '" + n + "'; skipped");
            while (const Token* t = in_.Peek()) {
                if (IsDirectiveName(*t)) break;
                in_.Next(d.loc, "");
            }
            return;
        }
        const std::string type = StringArg(d);
        if (n == "Texture") {
            const std::string value_type = StringArg(d);
            const std::string cls = StringArg(d);
            ParamSet ps = ReadParams(in_);
            return Texture(d.loc, type, value_type, cls, ps);
        }
        ParamSet ps = ReadParams(in_);
        const std::string desc = n + " \"" + type + "\"";
        if (n == "Camera") {
            Camera(d.loc, type, ps);
        } else if (n == "Sampler") {
            Sampler(d.loc, type, ps);
        } else if (n == "Film") {
            Film(d.loc, ps);
        } else if (n == "PixelFilter") {
            PixelFilter(d.loc, type, ps);
        } else if (n == "Integrator") {
            Integrator(d.loc, type, ps);
        } else if (n == "Accelerator") {
            ps.MarkAllUsed();
            Warn(d.loc, "Accelerator: Tessera builds its own (Embree); ignored");
        } else if (n == "Material") {
            Material(d.loc, type, ps, desc);
        } else if (n == "MakeNamedMaterial") {
            MakeNamedMaterial(d.loc, type, ps);
        } else if (n == "LightSource") {
            LightSource(d.loc, type, ps, desc);
        } else if (n == "AreaLightSource") {
            AreaLightSource(d.loc, type, ps, desc);
        } else if (n == "Shape") {
            Shape(d.loc, type, ps, desc);
        } else {  // MakeNamedMedium, Attribute
            ps.MarkAllUsed();
            Warn(d.loc, n +
                            (n == "MakeNamedMedium" ? ": participating media are not supported"
                                                    : ": not supported") +
                            "; ignored");
        }
        ReportUnused(ps, desc);
    }

    // --- transforms and state

    // pbrt post-multiplies: the last transform given applies to the shape first.
    void ApplyTransform(const M4& m, bool replace = false) {
        if (!transforms_active_) return;
        state_.ctm = replace ? m : state_.ctm * m;
    }

    void LookAt(const Token& d, const std::vector<double>& v) {
        const V3 eye{v[0], v[1], v[2]}, look{v[3], v[4], v[5]}, up{v[6], v[7], v[8]};
        const V3 dir = Normalized(look - eye);
        const V3 right = Cross(Normalized(up), dir);
        if (Length(look - eye) == 0 || !(Length(right) > 1e-9))
            return Warn(d.loc,
                        "LookAt: the up vector is parallel to the view (or eye equals "
                        "target); skipped");
        const V3 r = Normalized(right), new_up = Cross(dir, r);
        M4 world_from_camera = M4::Identity();
        const V3 cols[4] = {r, new_up, dir, eye};
        for (int j = 0; j < 4; ++j) {
            world_from_camera.m[0][j] = cols[j].x;
            world_from_camera.m[1][j] = cols[j].y;
            world_from_camera.m[2][j] = cols[j].z;
        }
        M4 camera_from_world;
        Invert(world_from_camera, &camera_from_world);
        ApplyTransform(camera_from_world);
    }

    struct Saved {
        GraphicsState state;
        bool transform_only;
        Loc loc;
    };

    void PopState(const Token& d) {
        const bool transform_only = d.text == "TransformEnd";
        if (stack_.empty()) return Warn(d.loc, d.text + " without a matching begin; ignored");
        if (stack_.back().transform_only != transform_only)
            Warn(d.loc, d.text + " closes the " +
                            (stack_.back().transform_only ? "TransformBegin" : "AttributeBegin") +
                            " of line " + std::to_string(stack_.back().loc.line));
        if (stack_.back().transform_only)
            state_.ctm = stack_.back().state.ctm;
        else
            state_ = stack_.back().state;
        stack_.pop_back();
    }

    void Include(const Token& d, const std::string& written) {
        if (in_.Depth() >= size_t(kMaxIncludeDepth))
            SyntaxError(d.loc, d.text + " \"" + written + "\": includes nest deeper than " +
                                   std::to_string(kMaxIncludeDepth) + " files (a cycle?)");
        std::string text;
        try {
            text = read_include_(written);
        } catch (const SceneError& e) {
            SyntaxError(d.loc, d.text + " \"" + written + "\": " + e.what());
        } catch (const std::exception& e) {
            SyntaxError(d.loc, d.text + " \"" + written + "\": " + e.what());
        }
        if (std::find(included_.begin(), included_.end(), written) == included_.end())
            included_.push_back(written);
        fs::path p(written);
        const std::string shown =
            p.is_absolute() ? written
                            : (fs::path(shown_).parent_path() / p).lexically_normal().string();
        in_.Push(Tokenizer(std::make_shared<const std::string>(shown), std::move(text)));
    }

    // pbrt's camera space is left-handed: the image's right is up x forward. Tessera's
    // camera sees forward x up on its right. Unless the pbrt camera is itself mirrored, the
    // world is mirrored (z -> -z), which turns the image the right way round and keeps
    // every facing (mirrored shapes keep their fronts in both renderers).
    void DecideMirror() {
        if (mirror_decided_) return;
        mirror_decided_ = true;
        M4 world_from_camera = M4::Identity();
        if (camera_ && !Invert(camera_->camera_from_world, &world_from_camera))
            world_from_camera = M4::Identity();
        const V3 r = world_from_camera.Column(0), u = world_from_camera.Column(1),
                 f = world_from_camera.Column(2);
        world_ = Dot(Cross(u, f), r) > 0 ? ScaleM({1, 1, -1}) : M4::Identity();
    }

    void WorldBegin(const Token& d) {
        if (in_world_) Warn(d.loc, "a second WorldBegin; ignored");
        in_world_ = true;
        DecideMirror();
        state_.ctm = M4::Identity();
        named_coordinates_["world"] = state_.ctm;
    }

    // --- rendering options

    struct CameraState {
        M4 camera_from_world = M4::Identity();
        double fov = 90, lens_radius = 0, focal_distance = 1e6;
        Loc loc;
    };

    void Camera(const Loc& loc, const std::string& type, ParamSet& ps) {
        CameraState c;
        c.camera_from_world = state_.ctm;
        c.loc = loc;
        M4 world_from_camera;
        if (Invert(state_.ctm, &world_from_camera))
            named_coordinates_["camera"] = world_from_camera;
        if (type != "perspective") {
            ps.MarkAllUsed();
            Warn(loc, "Camera \"" + type + "\" is not supported; a perspective camera is used");
        }
        c.fov = ps.Float("fov", 90);
        c.lens_radius = ps.Float("lensradius", 0);
        c.focal_distance = ps.Float("focaldistance", 1e6);
        if (!(c.fov > 0 && c.fov < 180)) {
            Warn(loc, "Camera: fov " + Num(c.fov) + " is outside (0, 180); 90 is used");
            c.fov = 90;
        }
        camera_ = c;
    }

    void Sampler(const Loc& loc, const std::string& type, ParamSet& ps) {
        sampler_loc_ = loc;
        if (type == "stratified") {
            sampler_ = "stratified";
            spp_ = int64_t(ps.Int("xsamples", 4)) * ps.Int("ysamples", 4);
            ps.Bool("jitter", true);
        } else {
            sampler_ = type == "independent" || type == "random" ? "independent" : "sobol";
            spp_ = ps.Int("pixelsamples", 16);
        }
        if (ps.Get("seed", {"integer"})) seed_ = ps.Int("seed", 0);
    }

    void Film(const Loc& loc, ParamSet& ps) {
        film_loc_ = loc;
        width_ = ps.Int("xresolution", 1280);
        height_ = ps.Int("yresolution", 720);
        if (ps.Get("filename", {"string"}))
            Warn(loc,
                 "Film: \"filename\" is ignored: the output file is named on the command "
                 "line (-o)");
    }

    void PixelFilter(const Loc& loc, const std::string& type, ParamSet& ps) {
        filter_loc_ = loc;
        // pbrt-v4 names the half-widths xradius/yradius, pbrt-v3 xwidth/ywidth.
        auto radius = [&](double def) {
            const double x = ps.Float("xradius", ps.Float("xwidth", def));
            const double y = ps.Float("yradius", ps.Float("ywidth", def));
            if (x != y)
                Warn(loc,
                     "PixelFilter: x and y radii differ; Tessera's filters are round, the "
                     "larger is used");
            return std::max(x, y);
        };
        JsonMembers f;
        if (type == "box") {
            f.Add("type", Quote("box")).Add("radius", Num(radius(0.5)));
        } else if (type == "gaussian") {
            const double r = radius(1.5);
            double sigma = ps.Float("sigma", 0.5);
            // pbrt-v3: exp(-alpha x^2).
            if (Param* a = ps.Get("alpha", {"float"});
                a && !a->numbers.empty() && a->numbers[0] > 0)
                sigma = 1 / std::sqrt(2 * a->numbers[0]);
            f.Add("type", Quote("gaussian")).Add("radius", Num(r)).Add("sigma", Num(sigma));
        } else if (type == "mitchell") {
            f.Add("type", Quote("mitchell"))
                .Add("radius", Num(radius(2)))
                .Add("b", Num(ps.Float("B", 1.0 / 3)))
                .Add("c", Num(ps.Float("C", 1.0 / 3)));
        } else if (type == "triangle") {
            f.Add("type", Quote("tent")).Add("radius", Num(radius(2)));
        } else {
            ps.MarkAllUsed();
            Warn(loc, "PixelFilter \"" + type +
                          "\" is not supported; pbrt-v4's default Gaussian is used");
            return;
        }
        filter_ = f.Str();
    }

    void Integrator(const Loc& loc, const std::string& type, ParamSet& ps) {
        integrator_loc_ = loc;
        max_depth_ = ps.Int("maxdepth", 5);
        if (type == "path" || type == "volpath") {
            integrator_ = "path";
        } else if (type == "bdpt") {
            integrator_ = "bdpt";
        } else if (type == "lightpath") {
            integrator_ = "light";
        } else if (type == "directlighting") {
            integrator_ = "direct";
        } else if (type == "mlt") {
            integrator_ = "mlt";
            JsonMembers m;
            if (ps.Get("mutationsperpixel", {"integer"}))
                mlt_spp_ = ps.Int("mutationsperpixel", 100);
            if (ps.Get("bootstrapsamples", {"integer"}))
                m.Add("bootstrap_samples", std::to_string(ps.Int("bootstrapsamples", 100000)));
            if (ps.Get("chains", {"integer"}))
                m.Add("chains", std::to_string(ps.Int("chains", 1000)));
            if (ps.Get("largestepprobability", {"float"}))
                m.Add("p_large", Num(ps.Float("largestepprobability", 0.3)));
            mlt_ = m.Str();
        } else {
            integrator_ = "path";
            Warn(loc, "Integrator \"" + type + "\" is not supported; \"path\" is used");
        }
        if (ps.Get("rrthreshold", {"float"})) rr_threshold_ = ps.Float("rrthreshold", 1);
    }

    // --- colours, textures, materials

    // A colour parameter, of any of the types that can give one.
    static Param* GetColor(ParamSet& ps, const std::string& name) {
        return ps.Get(name, {"rgb", "spectrum", "blackbody", "xyz", "float"});
    }

    // pbrt-v4's named spectra that have an obvious RGB value; others become grey.
    Rgb NamedSpectrum(const std::string& name, const Loc& loc, Rgb def) {
        if (name == "stdillum-D65") return Rgb(1);
        if (name == "stdillum-A") return BlackbodyRgb(2856);  // A is a 2856 K black body
        for (const NamedGlass& g : kGlasses)
            if (name == g.name) return Rgb(float(g.eta));
        Warn(loc, "spectrum \"" + name + "\" has no RGB equivalent here; the grey " + JsonRgb(def) +
                      " is used");
        return def;
    }

    // A colour parameter of any spectral type; `def` when absent.
    Rgb Color(ParamSet& ps, const std::string& name, SpectrumKind kind, Rgb def) {
        const Param* p = GetColor(ps, name);
        return p ? ColorOf(*p, kind, def) : def;
    }

    Rgb ColorOf(const Param& p, SpectrumKind kind, Rgb def) {
        const std::vector<double>& v = p.numbers;
        if (p.type == "rgb") return Rgb(float(v[0]), float(v[1]), float(v[2]));
        if (p.type == "xyz") return ClampedRgb(XyzToLinearSrgb({v[0], v[1], v[2]}));
        if (p.type == "float") return v.empty() ? def : Rgb(float(v[0]));
        if (p.type == "blackbody") {
            if (v.empty()) return def;
            return BlackbodyRgb(v[0]) * float(v.size() >= 2 ? v[1] : 1.0);
        }
        if (!p.strings.empty()) return NamedSpectrum(p.strings[0], p.loc, def);
        if (v.size() == 1) return Rgb(float(v[0]));
        const SpectrumFn s = PiecewiseLinear(v);
        switch (kind) {
            case SpectrumKind::kIlluminant:
                return IlluminantRgb(s);
            case SpectrumKind::kAlbedo:
                return AlbedoRgb(s);
            case SpectrumKind::kUnbounded:
                break;
        }
        // Representative wavelengths of R, G and B.
        return Rgb(float(s(610)), float(s(550)), float(s(465)));
    }

    // A float parameter that may also be a (constant) float texture.
    double FloatOrTexture(ParamSet& ps, const std::string& name, double def) {
        if (Param* t = ps.Get(name, {"texture"}); t && !t->strings.empty()) {
            auto it = float_textures_.find(t->strings[0]);
            if (it != float_textures_.end() && it->second) return *it->second;
            Warn(t->loc, "\"" + name + "\": float texture '" + t->strings[0] +
                             "' is not a constant texture; " + Num(def) + " is used");
            return def;
        }
        return ps.Float(name, def);
    }

    // A reflectance (albedo) as JSON: a colour within [0, 1] or the name of an image texture.
    std::string Reflectance(ParamSet& ps, const std::string& name, double def) {
        if (Param* t = ps.Get(name, {"texture"}); t && !t->strings.empty()) {
            auto it = spectrum_textures_.find(t->strings[0]);
            if (it != spectrum_textures_.end() && it->second.constant)
                return JsonRgb(ClampAlbedo(*it->second.constant, t->loc, name));
            if (it != spectrum_textures_.end() && !it->second.json_name.empty())
                return Quote(it->second.json_name);
            Warn(t->loc, "\"" + name + "\": texture '" + t->strings[0] + "' is not available; " +
                             Num(def) + " is used");
            return Num(def);
        }
        const Param* p = GetColor(ps, name);
        if (!p) return Num(def);
        return JsonRgb(
            ClampAlbedo(ColorOf(*p, SpectrumKind::kAlbedo, Rgb(float(def))), p->loc, name));
    }

    Rgb ClampAlbedo(Rgb c, const Loc& loc, const std::string& name) {
        const Rgb clamped(std::clamp(c.r, 0.0f, 1.0f), std::clamp(c.g, 0.0f, 1.0f),
                          std::clamp(c.b, 0.0f, 1.0f));
        if (!(clamped.r == c.r && clamped.g == c.g && clamped.b == c.b))
            Warn(loc, "\"" + name + "\" " + JsonRgb(c) +
                          " is clamped to [0, 1] (a reflectance above 1 creates energy)");
        return clamped;
    }

    void Texture(const Loc& loc, const std::string& name, const std::string& value_type,
                 const std::string& cls, ParamSet& ps) {
        const std::string desc = "Texture \"" + name + "\" \"" + value_type + "\" \"" + cls + "\"";
        const bool is_float = value_type == "float";
        if (is_float) {
            float_textures_[name] = std::nullopt;
            if (cls == "constant") {
                float_textures_[name] = FloatOrTexture(ps, "value", 1);
            } else {
                ps.MarkAllUsed();
                Warn(loc, desc +
                              ": only constant float textures are supported; parameters "
                              "that use it get their defaults");
            }
        } else {
            SpectrumTexture t;
            if (cls == "constant") {
                t.constant = Color(ps, "value", SpectrumKind::kAlbedo, Rgb(1));
            } else if (cls == "imagemap") {
                t.json_name = UniqueName(textures_names_, name);
                JsonMembers j;
                j.Add("type", Quote("image")).Add("file", Quote(ps.String("filename")));
                const std::string encoding = ps.String("encoding");
                if (encoding == "sRGB" || encoding == "linear")
                    j.Add("srgb", encoding == "sRGB" ? "true" : "false");
                else if (!encoding.empty())
                    Warn(loc, desc + ": encoding \"" + encoding +
                                  "\" is not supported; the "
                                  "file type's default is used");
                if (ps.Get("gamma", {"bool"}))
                    j.Add("srgb", ps.Bool("gamma", false) ? "true" : "false");
                auto expect = [&](const std::string& key, double def) {
                    if (ps.Get(key, {"float"}) && ps.Float(key, def) != def)
                        Warn(loc, desc + ": \"" + key + "\" is not supported; ignored");
                };
                expect("scale", 1);
                expect("uscale", 1);
                expect("vscale", 1);
                expect("udelta", 0);
                expect("vdelta", 0);
                expect("su", 1);
                expect("sv", 1);
                expect("du", 0);
                expect("dv", 0);
                ps.String("filter");
                ps.Float("maxanisotropy", 8);
                if (ps.Bool("invert", false)) Warn(loc, desc + ": \"invert\" is not supported");
                const std::string wrap = ps.String("wrap", "repeat");
                if (wrap != "repeat") Warn(loc, desc + ": wrap \"" + wrap + "\"; Tessera repeats");
                const std::string mapping = ps.String("mapping", "uv");
                if (mapping != "uv") Warn(loc, desc + ": mapping \"" + mapping + "\"; uv is used");
                textures_.emplace_back(t.json_name, j.Str());
                origins_.emplace_back("/textures/" + PointerKey(t.json_name), loc.Str());
            } else {
                ps.MarkAllUsed();
                Warn(loc, desc + ": texture class \"" + cls +
                              "\" is not supported; parameters "
                              "that use it get their defaults");
            }
            spectrum_textures_[name] = t;
        }
        ReportUnused(ps, desc);
    }

    static std::string UniqueName(std::set<std::string>& used, const std::string& base) {
        std::string name = base;
        for (int i = 2; used.count(name); ++i) name = base + " #" + std::to_string(i);
        used.insert(name);
        return name;
    }

    // pbrt-v3 remaps roughness to a microfacet alpha by a polynomial in log(roughness),
    // pbrt-v4 by its square root.
    static double RoughnessToAlpha(double r, bool v3) {
        if (!v3) return std::sqrt(std::max(r, 0.0));
        const double x = std::log(std::max(r, 1e-3));
        return 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x +
               0.000640711 * x * x * x * x;
    }

    // (alpha_u, alpha_v) from roughness, uroughness, vroughness and remaproughness.
    std::pair<double, double> Alpha(ParamSet& ps, double def, bool v3) {
        const double r = FloatOrTexture(ps, "roughness", def);
        double u = FloatOrTexture(ps, "uroughness", r), v = FloatOrTexture(ps, "vroughness", r);
        // A roughness of 0 stays smooth (pbrt-v3's polynomial is not 0 there).
        if (ps.Bool("remaproughness", true)) {
            u = u > 0 ? RoughnessToAlpha(u, v3) : 0;
            v = v > 0 ? RoughnessToAlpha(v, v3) : 0;
        }
        return {u, v};
    }

    static double ClampAlpha(double a) { return std::clamp(a, 0.001, 1.0); }

    void AddAlphaTooHigh(const Loc& loc, double a) {
        if (a > 1) Warn(loc, "microfacet alpha " + Num(a) + " is clamped to 1");
    }

    // Conductor: Tessera's named metal when eta and k name one, else RGB eta and k.
    void Conductor(JsonMembers& j, ParamSet& ps, const Loc& loc) {
        if (const Param* r = GetColor(ps, "reflectance")) {
            // pbrt-v4's artist-friendly conductor: eta = 1, k = 2 sqrt(r) / sqrt(1 - r).
            const Rgb c = ColorOf(*r, SpectrumKind::kAlbedo, Rgb(0.5f));
            Rgb k;
            for (int i = 0; i < 3; ++i) {
                const float x = std::clamp(c[i], 0.0f, 0.9999f);
                k[i] = 2 * std::sqrt(x) / std::sqrt(1 - x);
            }
            j.Add("eta", Num(1)).Add("k", JsonRgb(k));
            return;
        }
        const Param* eta = GetColor(ps, "eta");
        const Param* k = GetColor(ps, "k");
        auto metal_of = [](const Param* p) -> std::optional<std::pair<std::string, std::string>> {
            if (!p || p->type != "spectrum" || p->strings.empty()) return std::nullopt;
            return MetalSpectrum(p->strings[0]);
        };
        const auto me = metal_of(eta), mk = metal_of(k);
        std::string metal;
        if (!eta && !k) metal = "Cu";  // pbrt's default: metal-Cu-eta, metal-Cu-k
        if (me && kTesseraMetals.count(me->first) && (!k || (mk && mk->first == me->first)))
            metal = me->first;
        if (mk && kTesseraMetals.count(mk->first) && !eta) metal = mk->first;
        if (!metal.empty()) {
            j.Add("metal", Quote(metal));
            return;
        }
        if ((me && kTesseraMetals.count(me->first)) || (mk && kTesseraMetals.count(mk->first)))
            Warn(loc, "conductor: eta and k do not name the same metal; each is converted alone");
        // Spectra that name metals Tessera does not know become a neutral metal.
        auto value = [&](const Param* p, Rgb def) {
            if (!p) return def;
            if (metal_of(p)) {
                Warn(p->loc, "spectrum \"" + p->strings[0] +
                                 "\" has no RGB equivalent here; "
                                 "the grey " +
                                 JsonRgb(def) + " is used");
                return def;
            }
            return ColorOf(*p, SpectrumKind::kUnbounded, def);
        };
        j.Add("eta", JsonRgb(value(eta, Rgb(1.2f)))).Add("k", JsonRgb(value(k, Rgb(3.0f))));
    }

    // Dielectric index of refraction: a number, or a spectrum at 587.6 nm.
    double Eta(ParamSet& ps, const std::string& name, double def) {
        Param* p = ps.Get(name, {"float", "spectrum"});
        if (!p) return def;
        if (p->type == "float") return p->numbers.empty() ? def : p->numbers[0];
        if (!p->strings.empty()) {
            for (const NamedGlass& g : kGlasses)
                if (p->strings[0] == g.name) return g.eta;
            Warn(p->loc, "\"" + name + "\": spectrum \"" + p->strings[0] +
                             "\" is not a glass pbrt names; " + Num(def) + " is used");
            return def;
        }
        if (p->numbers.size() == 1) return p->numbers[0];
        return PiecewiseLinear(p->numbers)(587.6);
    }

    // One material's JSON record; nullopt for pbrt's "interface" and "none" (no surface).
    std::optional<std::string> ConvertMaterial(const std::string& type, ParamSet& ps,
                                               const Loc& loc, const std::string& desc) {
        JsonMembers j;
        if (type == "diffuse" || type == "matte") {
            j.Add("type", Quote("diffuse"))
                .Add("reflectance", Reflectance(ps, type == "matte" ? "Kd" : "reflectance", 0.5));
            if (type == "matte" && FloatOrTexture(ps, "sigma", 0) != 0)
                Warn(loc, desc + ": Oren-Nayar \"sigma\" is not supported; Lambertian is used");
        } else if (type == "conductor" || type == "metal") {
            const auto [u, v] = Alpha(ps, type == "metal" ? 0.01 : 0, type == "metal");
            if (u < 0.001 && v < 0.001) {
                j.Add("type", Quote("conductor"));
                Conductor(j, ps, loc);
            } else {
                j.Add("type", Quote("roughconductor"));
                Conductor(j, ps, loc);
                AddAlphaTooHigh(loc, std::max(u, v));
                if (u == v)
                    j.Add("alpha", Num(ClampAlpha(u)));
                else
                    j.Add("alpha_u", Num(ClampAlpha(u))).Add("alpha_v", Num(ClampAlpha(v)));
            }
        } else if (type == "mirror") {
            j.Add("type", Quote("mirror")).Add("reflectance", Reflectance(ps, "Kr", 0.9));
        } else if (type == "dielectric" || type == "glass" || type == "thindielectric") {
            if (type == "thindielectric")
                Warn(loc, desc + ": a thin dielectric is converted to a solid one");
            double eta = Eta(ps, "eta", 1.5);
            if (type == "glass" && ps.Has("index")) eta = Eta(ps, "index", 1.5);
            if (type == "glass") {
                for (const char* key : {"Kr", "Kt"}) {
                    if (!ps.Has(key)) continue;
                    const Rgb c = Color(ps, key, SpectrumKind::kAlbedo, Rgb(1));
                    if (c.r != 1 || c.g != 1 || c.b != 1)
                        Warn(loc, desc + ": \"" + key + "\" other than 1 is not supported");
                }
            }
            const auto [u, v] = Alpha(ps, 0, type == "glass");
            if (eta == 1 || !(eta > 0)) {
                Warn(loc, desc + ": eta " + Num(eta) +
                              " makes no visible surface; shapes with "
                              "it are skipped");
                return std::nullopt;
            }
            if (u < 0.001 && v < 0.001) {
                j.Add("type", Quote("dielectric")).Add("eta", Num(eta));
            } else {
                if (u != v)
                    Warn(loc, desc +
                                  ": anisotropic roughness is not supported for glass; the "
                                  "mean is used");
                const double a = (u + v) / 2;
                AddAlphaTooHigh(loc, a);
                j.Add("type", Quote("roughdielectric"))
                    .Add("eta", Num(eta))
                    .Add("alpha", Num(ClampAlpha(a)));
            }
        } else if (type == "coateddiffuse" || type == "plastic") {
            const bool v3 = type == "plastic";
            j.Add("type", Quote("plastic"))
                .Add("reflectance", Reflectance(ps, v3 ? "Kd" : "reflectance", v3 ? 0.25 : 0.5));
            const double eta = v3 ? 1.5 : Eta(ps, "eta", 1.5);
            if (eta != 1.5 && eta > 0 && eta != 1) j.Add("eta", Num(eta));
            const auto [u, v] = Alpha(ps, v3 ? 0.1 : 0, v3);
            const double a = (u + v) / 2;
            AddAlphaTooHigh(loc, a);
            if (a > 0) j.Add("alpha", Num(std::min(a, 1.0)));
            if (v3 && ps.Has("Ks")) {
                Color(ps, "Ks", SpectrumKind::kAlbedo, Rgb(0.25f));
                Warn(loc, desc + ": \"Ks\" is not supported: the coat is a dielectric of eta 1.5");
            }
            if (!v3) {
                for (const char* key : {"thickness", "g", "maxdepth", "nsamples", "albedo"}) {
                    if (!ps.Has(key)) continue;
                    Warn(loc, desc + ": \"" + std::string(key) +
                                  "\" is not supported (Tessera's coat has no layer medium)");
                    for (Param& q : ps.params)
                        if (q.name == key) q.used = true;
                }
            }
        } else if (type == "mix") {
            return MixMaterial(ps, loc, desc);
        } else if (type == "interface" || type == "none" || type.empty()) {
            Warn(loc, desc +
                          ": shapes with this material are skipped unless they emit "
                          "(participating media are not supported)");
            return std::nullopt;
        } else {
            // What pbrt-v3's uber, substrate and translucent share: a diffuse colour.
            const std::string kd = ps.Has("Kd") ? "Kd" : "reflectance";
            const std::string refl = Reflectance(ps, kd, 0.5);
            ps.MarkAllUsed();
            Warn(loc, desc + ": material \"" + type + "\" is not supported; a diffuse " + refl +
                          " is used");
            j.Add("type", Quote("diffuse")).Add("reflectance", refl);
        }
        return j.Str();
    }

    std::optional<std::string> MixMaterial(ParamSet& ps, const Loc& loc, const std::string& desc) {
        // pbrt-v4: "materials" [a b], b with probability "amount"; pbrt-v3: namedmaterial1
        // and namedmaterial2, the first weighted by "amount".
        std::vector<std::string> names;
        bool v3 = false;
        if (Param* m = ps.Get("materials", {"string"})) names = m->strings;
        if (names.empty()) {
            v3 = true;
            names = {ps.String("namedmaterial1"), ps.String("namedmaterial2")};
        }
        double amount = FloatOrTexture(ps, "amount", 0.5);
        if (v3) amount = 1 - amount;
        std::vector<std::string> parts;
        for (const std::string& n : names) {
            auto it = named_materials_.find(n);
            if (it == named_materials_.end() || !it->second.second) {
                Warn(loc, desc + ": material '" + n +
                              "' is unknown or has no surface; the "
                              "default is used in its place");
                parts.push_back(DefaultMaterial());
            } else {
                parts.push_back(it->second.first);
            }
        }
        if (parts.size() != 2) {
            Warn(loc, desc + ": a mix needs two materials; pbrt's default is used");
            return JsonMembers().Add("type", Quote("diffuse")).Add("reflectance", "0.5").Str();
        }
        return JsonMembers()
            .Add("type", Quote("blend"))
            .Add("materials", "[" + Quote(parts[0]) + ", " + Quote(parts[1]) + "]")
            .Add("weight", Num(std::clamp(amount, 0.0, 1.0)))
            .Str();
    }

    std::string AddMaterial(const std::string& base, const std::string& json, const Loc& loc) {
        const std::string name = UniqueName(material_names_, base);
        materials_.emplace_back(name, json);
        origins_.emplace_back("/materials/" + PointerKey(name), loc.Str());
        return name;
    }

    std::string DefaultMaterial() {
        if (default_material_.empty())
            default_material_ = AddMaterial(
                "pbrt default",
                JsonMembers().Add("type", Quote("diffuse")).Add("reflectance", "0.5").Str(),
                Loc{std::make_shared<const std::string>(shown_), 1});
        return default_material_;
    }

    void Material(const Loc& loc, const std::string& type, ParamSet& ps, const std::string& desc) {
        const std::optional<std::string> json = ConvertMaterial(type, ps, loc, desc);
        state_.surface = bool(json);
        state_.material = json ? AddMaterial(loc.Str(), *json, loc) : "";
    }

    void MakeNamedMaterial(const Loc& loc, const std::string& name, ParamSet& ps) {
        const std::string type = ps.String("type");
        const std::string desc = "MakeNamedMaterial \"" + name + "\" (\"" + type + "\")";
        if (type.empty()) Warn(loc, "MakeNamedMaterial \"" + name + "\" has no \"string type\"");
        if (named_materials_.count(name))
            Warn(loc, "MakeNamedMaterial: \"" + name + "\" is defined again; the new one applies");
        const std::optional<std::string> json = ConvertMaterial(type, ps, loc, desc);
        named_materials_[name] = {json ? AddMaterial(name, *json, loc) : "", bool(json)};
    }

    // --- lights

    Rgb LightScale(ParamSet& ps) { return Color(ps, "scale", SpectrumKind::kUnbounded, Rgb(1)); }

    void AddLight(const std::string& json, const Loc& loc) {
        origins_.emplace_back("/lights/" + std::to_string(lights_.size()), loc.Str());
        lights_.push_back(json);
    }

    void LightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                     const std::string& desc) {
        if (current_object_) {
            ps.MarkAllUsed();
            return Warn(loc,
                        desc + ": lights inside an object definition are not supported; skipped");
        }
        DecideMirror();
        const M4 xf = world_ * state_.ctm;
        JsonMembers j;
        if (type == "point") {
            const Rgb i = Color(ps, "I", SpectrumKind::kIlluminant, Rgb(1)) * LightScale(ps);
            j.Add("type", Quote("point"))
                .Add("position", JsonVec(xf.Point(ps.Point("from", {}))))
                .Add("intensity", JsonRgb(i));
        } else if (type == "spot") {
            const Rgb i = Color(ps, "I", SpectrumKind::kIlluminant, Rgb(1)) * LightScale(ps);
            const V3 from = ps.Point("from", {}), to = ps.Point("to", {0, 0, 1});
            const double cone = std::clamp(ps.Float("coneangle", 30), 1e-3, 180.0);
            const double delta = ps.Float("conedelta", 5);
            if (Length(to - from) == 0) return Warn(loc, desc + ": from equals to; skipped");
            j.Add("type", Quote("spot"))
                .Add("position", JsonVec(xf.Point(from)))
                .Add("target", JsonVec(xf.Point(to)))
                .Add("intensity", JsonRgb(i))
                .Add("cone_angle", Num(cone))
                .Add("falloff_start", Num(std::clamp(cone - delta, 0.0, cone)));
        } else if (type == "distant") {
            const Rgb l = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1)) * LightScale(ps);
            const V3 from = ps.Point("from", {}), to = ps.Point("to", {0, 0, 1});
            const V3 dir = xf.Vector(to - from);
            if (Length(dir) == 0) return Warn(loc, desc + ": from equals to; skipped");
            j.Add("type", Quote("directional"))
                .Add("direction", JsonVec(Normalized(dir)))
                .Add("irradiance", JsonRgb(l));
        } else if (type == "infinite") {
            if (!InfiniteLight(j, ps, loc, desc, xf)) return;
        } else {
            ps.MarkAllUsed();
            return Warn(loc, desc + ": light type \"" + type + "\" is not supported; skipped");
        }
        AddLight(j.Str(), loc);
    }

    // A map's texel (u, v) lies, in pbrt's light space, at d_p = (sin t cos p, sin t sin p,
    // cos t) with t = pi v, p = 2 pi u (pbrt-v3's latitude-longitude layout), and, in
    // Tessera's map frame, at d_t = (sin t cos p, cos t, -sin t sin p): d_p = A d_t. In
    // Tessera's world the texel must lie at W L d_p (W the world's mirror, L light to
    // world), so the map turns by W L A: a rotation, or a mirror (u -> 1 - u, Tessera's
    // "mirror", F = diag(1, 1, -1) on d_t) followed by the rotation W L A F.
    bool InfiniteLight(JsonMembers& j, ParamSet& ps, const Loc& loc, const std::string& desc,
                       const M4& xf) {
        const bool has_l = ps.Has("L");
        const Rgb l = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1));
        const Rgb scale = LightScale(ps);
        std::string file = ps.String("mapname");
        if (Param* f = ps.Get("filename", {"string"}); f && !f->strings.empty()) {
            file = f->strings[0];
            Warn(f->loc,
                 desc + ": \"" + file +
                     "\" is read as a latitude-longitude map in "
                     "pbrt-v3's layout (\"mapname\"); pbrt-v4's square equal-area maps must "
                     "be converted to that layout first");
            if (has_l) Warn(loc, desc + ": both \"L\" and a map; the map is scaled by L");
        }
        j.Add("type", Quote("environment"));
        if (file.empty()) {
            j.Add("radiance", JsonRgb(l * scale));
            return true;
        }
        M4 rotation = M4::Identity();  // the light's frame, without scale
        for (int c = 0; c < 3; ++c) {
            const V3 col = Normalized(xf.Column(c));
            rotation.m[0][c] = col.x;
            rotation.m[1][c] = col.y;
            rotation.m[2][c] = col.z;
        }
        const V3 c0 = rotation.Column(0), c1 = rotation.Column(1), c2 = rotation.Column(2);
        if (std::abs(Dot(c0, c1)) > 1e-4 || std::abs(Dot(c1, c2)) > 1e-4 ||
            std::abs(Dot(c0, c2)) > 1e-4)
            Warn(loc, desc + ": the light's transform shears; the map's rotation is approximate");
        M4 a = M4::Identity();
        a.m[1][1] = 0;
        a.m[1][2] = -1;
        a.m[2][1] = 1;
        a.m[2][2] = 0;
        M4 q = rotation * a;
        const bool mirror = q.Det3() < 0;
        if (mirror) q = q * ScaleM({1, 1, -1});
        j.Add("file", Quote(file)).Add("scale", JsonRgb(scale * (has_l ? l : Rgb(1))));
        if (std::abs(q.m[0][0] + q.m[1][1] + q.m[2][2] - 3) > 1e-12)  // not the identity
            j.Add("rotate", JsonRotation(q));
        if (mirror) j.Add("mirror", "true");
        return true;
    }

    void AreaLightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                         const std::string& desc) {
        if (type != "diffuse") {
            ps.MarkAllUsed();
            state_.area_light.reset();
            return Warn(loc, desc + ": area light type \"" + type +
                                 "\" is not supported; the "
                                 "shapes that follow do not emit");
        }
        AreaLight a;
        a.radiance = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1)) * LightScale(ps);
        a.two_sided = ps.Bool("twosided", false);
        state_.area_light = a;
    }

    // --- shapes

    // Tessera drops degenerate triangles, pbrt silently skips them: dropped here, counted.
    struct Mesh {
        std::vector<Vec3> positions;
        std::vector<uint32_t> indices;
        std::vector<Vec3> normals;
        std::vector<double> uvs;
    };

    std::optional<Mesh> ReadMesh(ParamSet& ps, const Loc& loc, const std::string& desc,
                                 bool bilinear) {
        const std::vector<double>* p = ps.Numbers("P", {"point3"});
        if (!p || p->empty()) {
            Warn(loc, desc + ": no \"point3 P\"; skipped");
            return std::nullopt;
        }
        Mesh m;
        const size_t nv = p->size() / 3;
        for (size_t i = 0; i < nv; ++i)
            m.positions.push_back(
                Vec3(float((*p)[3 * i]), float((*p)[3 * i + 1]), float((*p)[3 * i + 2])));
        std::vector<double> idx;
        if (const std::vector<double>* v = ps.Numbers("indices", {"integer"})) idx = *v;
        const size_t corners = bilinear ? 4 : 3;
        if (idx.empty() && nv == corners)
            for (size_t i = 0; i < corners; ++i) idx.push_back(double(i));
        if (idx.empty() || idx.size() % corners != 0) {
            Warn(loc, desc + ": \"indices\" must list " + std::to_string(corners) +
                          " vertices per " + (bilinear ? "patch" : "triangle") + "; skipped");
            return std::nullopt;
        }
        for (double i : idx) {
            if (i < 0 || i >= double(nv)) {
                Warn(loc, desc + ": vertex index " + Num(i) + " is out of range (" +
                              std::to_string(nv) + " vertices); skipped");
                return std::nullopt;
            }
        }
        if (const std::vector<double>* n = ps.Numbers("N", {"normal3"})) {
            bool ok = n->size() == 3 * nv;
            for (size_t i = 0; ok && i < nv; ++i) {
                const Vec3 v(float((*n)[3 * i]), float((*n)[3 * i + 1]), float((*n)[3 * i + 2]));
                ok = LengthSquared(v) > 0;
                m.normals.push_back(v);
            }
            if (!ok) {
                Warn(loc, desc + ": \"N\" is not one non-zero normal per vertex; ignored");
                m.normals.clear();
            }
        }
        const std::vector<double>* uv = ps.Numbers("uv", {"point2", "float"});
        if (!uv) uv = ps.Numbers("st", {"point2", "float"});
        if (uv) {
            if (uv->size() == 2 * nv)
                m.uvs = *uv;
            else
                Warn(loc, desc + ": \"uv\" is not one pair per vertex; ignored");
        }

        // Triangle (i, j, k) faces where pbrt's does: towards the shading normals if there
        // are any (pbrt turns its geometric normal that way), else per ReverseOrientation.
        size_t degenerate = 0;
        auto add = [&](uint32_t i, uint32_t j, uint32_t k) {
            const Vec3 &a = m.positions[i], &b = m.positions[j], &c = m.positions[k];
            const Vec3 ng = tessera::Cross(b - a, c - a);
            if (i == j || j == k || i == k || LengthSquared(ng) == 0) {
                ++degenerate;
                return;
            }
            bool flip = state_.reverse_orientation;
            if (!m.normals.empty())
                flip = tessera::Dot(ng, m.normals[i] + m.normals[j] + m.normals[k]) < 0;
            if (flip) std::swap(j, k);
            m.indices.insert(m.indices.end(), {i, j, k});
        };
        for (size_t f = 0; f < idx.size(); f += corners) {
            const auto v = [&](size_t c) { return uint32_t(idx[f + c]); };
            if (bilinear) {  // corners p00, p10, p01, p11
                add(v(0), v(1), v(3));
                add(v(0), v(3), v(2));
            } else {
                add(v(0), v(1), v(2));
            }
        }
        if (degenerate > 0)
            Warn(loc, desc + ": " + std::to_string(degenerate) +
                          " degenerate triangle(s) (zero area) dropped");
        if (m.indices.empty()) {
            Warn(loc, desc + ": no triangle with an area; skipped");
            return std::nullopt;
        }
        return m;
    }

    static std::string MeshJson(const Mesh& m) {
        std::string s = "\"positions\": [";
        s.reserve(m.positions.size() * 40 + m.indices.size() * 8);
        for (size_t i = 0; i < m.positions.size(); ++i)
            s += (i ? ", " : "") + Num(m.positions[i].x) + ", " + Num(m.positions[i].y) + ", " +
                 Num(m.positions[i].z);
        s += "], \"indices\": [";
        for (size_t i = 0; i < m.indices.size(); ++i)
            s += (i ? ", " : "") + std::to_string(m.indices[i]);
        s += "]";
        if (!m.normals.empty()) {
            s += ", \"normals\": [";
            for (size_t i = 0; i < m.normals.size(); ++i)
                s += (i ? ", " : "") + Num(m.normals[i].x) + ", " + Num(m.normals[i].y) + ", " +
                     Num(m.normals[i].z);
            s += "]";
        }
        if (!m.uvs.empty()) {
            s += ", \"uvs\": [";
            for (size_t i = 0; i < m.uvs.size(); ++i) s += (i ? ", " : "") + Num(m.uvs[i]);
            s += "]";
        }
        return s;
    }

    std::string ShapeMaterial() {
        return state_.material.empty() ? DefaultMaterial() : state_.material;
    }

    void Shape(const Loc& loc, const std::string& type, ParamSet& ps, const std::string& desc) {
        if (!in_world_) {
            ps.MarkAllUsed();
            return Warn(loc, desc + " before WorldBegin; skipped");
        }
        std::optional<AreaLight> emit = state_.area_light;
        if (emit && current_object_) {
            Warn(loc, desc +
                          ": area lights in object definitions are not supported (nor in "
                          "pbrt); the shape does not emit");
            emit.reset();
        }
        // The geometry's JSON members, and the transform from the shape's space.
        std::string geometry;
        M4 object_to_pbrt = state_.ctm;
        const bool swaps = state_.ctm.Det3() < 0;
        if (type == "trianglemesh" || type == "bilinearmesh" || type == "loopsubdiv") {
            if (type == "loopsubdiv" && ps.Int("levels", 3) > 0)
                Warn(loc, desc + ": subdivision is not supported; the control mesh is used");
            const std::optional<Mesh> m = ReadMesh(ps, loc, desc, type == "bilinearmesh");
            if (!m) return;
            geometry = "\"type\": \"triangles\", " + MeshJson(*m);
        } else if (type == "plymesh") {
            const std::string file = ps.String("filename");
            if (file.empty()) return Warn(loc, desc + ": no \"filename\"; skipped");
            if (file.size() > 3 && file.compare(file.size() - 3, 3, ".gz") == 0)
                return Warn(loc, desc +
                                     ": compressed PLY files (.ply.gz) are not supported; "
                                     "skipped");
            if (state_.reverse_orientation)
                Warn(loc, desc +
                              ": ReverseOrientation is not supported for PLY files; the "
                              "file's own orientation is kept");
            geometry = "\"type\": \"mesh\", \"file\": " + Quote(file);
        } else if (type == "sphere") {
            return Sphere(loc, ps, desc, emit);
        } else if (type == "disk") {
            const double h = ps.Float("height", 0), r = ps.Float("radius", 1);
            if (ps.Float("innerradius", 0) != 0 || ps.Float("phimax", 360) < 360)
                Warn(loc, desc +
                              ": partial disks (innerradius, phimax) are not supported; a full "
                              "disk is used");
            if (!(r > 0)) return Warn(loc, desc + ": radius must be positive; skipped");
            geometry = "\"type\": \"disk\", \"radius\": " + Num(r);
            object_to_pbrt = object_to_pbrt * TranslateM({0, 0, h});
            // pbrt turns a disk's normal (+z) by ReverseOrientation and by a mirroring
            // transform; a mirror in z maps the disk onto itself with the other face front.
            if (state_.reverse_orientation != swaps)
                object_to_pbrt = object_to_pbrt * ScaleM({1, 1, -1});
        } else {
            ps.MarkAllUsed();
            return Warn(loc, desc + ": shape \"" + type + "\" is not supported; skipped");
        }
        const M4 xf = world_ * object_to_pbrt;
        if (!xf.IsAffine() || !(std::abs(xf.Det3()) > 1e-30))
            return Warn(loc, desc + ": its transform is singular or projective; skipped");
        if (!state_.surface && !emit) return;  // "interface": nothing to see

        std::string s = "{\"name\": " + Quote(loc.Str()) + ", " + geometry;
        if (state_.surface) s += ", \"material\": " + Quote(ShapeMaterial());
        if (emit) s += ", \"emission\": " + EmissionJson(*emit);
        if (!xf.IsIdentity()) s += ", \"transform\": " + JsonMatrix(xf);
        s += "}";
        AddShape(s, loc);
    }

    static std::string EmissionJson(const AreaLight& a) {
        JsonMembers e;
        e.Add("radiance", JsonRgb(a.radiance));
        if (a.two_sided) e.Add("two_sided", "true");
        return e.Str();
    }

    void AddShape(const std::string& json, const Loc& loc) {
        if (current_object_) {
            current_object_->shapes.push_back(json);
            current_object_->shape_locs.push_back(loc);
            return;
        }
        origins_.emplace_back("/shapes/" + std::to_string(shapes_.size()), loc.Str());
        shapes_.push_back(json);
    }

    void Sphere(const Loc& loc, ParamSet& ps, const std::string& desc,
                const std::optional<AreaLight>& emit) {
        const double r = ps.Float("radius", 1);
        if (ps.Float("zmin", -r) > -r || ps.Float("zmax", r) < r || ps.Float("phimax", 360) < 360)
            Warn(loc, desc +
                          ": partial spheres (zmin, zmax, phimax) are not supported; a full "
                          "sphere is used");
        if (!(r > 0)) return Warn(loc, desc + ": radius must be positive; skipped");
        if (state_.reverse_orientation != (state_.ctm.Det3() < 0) && emit && !emit->two_sided)
            Warn(loc, desc +
                          ": an inward-facing emitting sphere (ReverseOrientation or a "
                          "mirroring transform) is not supported; it emits outward");
        if (!state_.surface && !emit) return;
        SphereDef s{state_.ctm, r, state_.surface ? ShapeMaterial() : "", loc};
        if (current_object_) {
            current_object_->spheres.push_back(s);
            return;
        }
        EmitSphere(s, M4::Identity(), emit);
    }

    // A sphere placed by `instance` * its own transform; Tessera's spheres stay round.
    void EmitSphere(const SphereDef& s, const M4& instance, const std::optional<AreaLight>& emit) {
        const M4 xf = world_ * instance * s.ctm;
        const double l0 = Length(xf.Column(0)), l1 = Length(xf.Column(1)),
                     l2 = Length(xf.Column(2));
        const double lo = std::min({l0, l1, l2}), hi = std::max({l0, l1, l2});
        const V3 c0 = xf.Column(0), c1 = xf.Column(1), c2 = xf.Column(2);
        const double shear =
            std::max({std::abs(Dot(c0, c1)), std::abs(Dot(c1, c2)), std::abs(Dot(c0, c2))}) /
            (hi * hi);
        if (hi - lo > 1e-5 * hi || shear > 1e-5)
            Warn(s.loc,
                 "Shape \"sphere\": a non-uniform scale or a shear is not supported; the "
                 "sphere stays round (its radius scaled by the mean)");
        JsonMembers j;
        j.Add("name", Quote(s.loc.Str()))
            .Add("type", Quote("sphere"))
            .Add("center", JsonVec(xf.Point({})))
            .Add("radius", Num(s.radius * (l0 + l1 + l2) / 3));
        if (!s.material.empty()) j.Add("material", Quote(s.material));
        if (emit) j.Add("emission", EmissionJson(*emit));
        origins_.emplace_back("/shapes/" + std::to_string(shapes_.size()), s.loc.Str());
        shapes_.push_back(j.Str());
    }

    // --- instancing

    void ObjectBegin(const Token& d, const std::string& name) {
        stack_.push_back({state_, false, d.loc});
        if (current_object_)
            Warn(d.loc, "ObjectBegin inside an object definition; the outer one ends");
        auto def = std::make_shared<ObjectDef>();
        def->json_name = UniqueName(object_names_, name);
        if (objects_.count(name)) Warn(d.loc, "ObjectBegin: \"" + name + "\" is defined again");
        objects_[name] = def;
        current_object_ = def;
        current_object_loc_ = d.loc;
    }

    void ObjectEnd(const Token& d) {
        if (!current_object_) return Warn(d.loc, "ObjectEnd without ObjectBegin; ignored");
        ObjectDef& def = *current_object_;
        if (!def.shapes.empty()) {
            const std::string ptr = "/objects/" + PointerKey(def.json_name);
            origins_.emplace_back(ptr, current_object_loc_.Str());
            for (size_t i = 0; i < def.shape_locs.size(); ++i)
                origins_.emplace_back(ptr + "/shapes/" + std::to_string(i),
                                      def.shape_locs[i].Str());
            std::string s;
            for (size_t i = 0; i < def.shapes.size(); ++i)
                s += (i ? ",\n    " : "") + def.shapes[i];
            object_json_.emplace_back(def.json_name, "{\"shapes\": [\n    " + s + "]}");
        }
        current_object_.reset();
        if (!stack_.empty()) {
            state_ = stack_.back().state;
            stack_.pop_back();
        }
    }

    void ObjectInstance(const Token& d, const std::string& name) {
        if (current_object_)
            return Warn(d.loc, "ObjectInstance inside an object definition; skipped");
        auto it = objects_.find(name);
        if (it == objects_.end())
            return Warn(d.loc, "ObjectInstance: unknown object '" + name + "'");
        const ObjectDef& def = *it->second;
        DecideMirror();
        // The object's shapes carry world_ * (their transform); the instance conjugates
        // pbrt's by the mirror (world_ is its own inverse), which composes to
        // world_ * instance * shape.
        if (!def.shapes.empty()) {
            const M4 xf = world_ * state_.ctm * world_;
            if (!xf.IsAffine() || !(std::abs(xf.Det3()) > 1e-30))
                return Warn(d.loc,
                            "ObjectInstance: its transform is singular or projective; skipped");
            JsonMembers j;
            j.Add("object", Quote(def.json_name));
            if (!xf.IsIdentity()) j.Add("transform", JsonMatrix(xf));
            origins_.emplace_back("/instances/" + std::to_string(instances_.size()), d.loc.Str());
            instances_.push_back(j.Str());
        }
        for (const SphereDef& s : def.spheres) EmitSphere(s, state_.ctm, std::nullopt);
    }

    // --- the converted scene

    PbrtImport Finish() {
        DecideMirror();
        if (current_object_) Warn(current_object_loc_, "ObjectBegin is never closed");
        PbrtImport out;
        out.shown = shown_;
        std::string s = "{\n";
        s += "\"render\": " + RenderJson() + ",\n";
        s += "\"camera\": " + CameraJson();
        auto section = [&](const std::string& key, const auto& entries, bool map) {
            if (entries.empty()) return;
            s += ",\n" + Quote(key) + (map ? ": {\n  " : ": [\n  ");
            bool first = true;
            for (const auto& e : entries) {
                if (!first) s += ",\n  ";
                first = false;
                if constexpr (std::is_same_v<std::decay_t<decltype(e)>, std::string>)
                    s += e;
                else
                    s += Quote(e.first) + ": " + e.second;
            }
            s += map ? "}" : "]";
        };
        section("textures", textures_, true);
        section("materials", materials_, true);
        section("shapes", shapes_, false);
        section("objects", object_json_, true);
        section("instances", instances_, false);
        section("lights", lights_, false);
        s += "\n}\n";
        out.json = std::move(s);
        for (const WarningEntry& w : warnings_)
            out.warnings.push_back(w.where + ": " + w.what +
                                   (w.more ? " (and " + std::to_string(w.more) + " more)" : ""));
        out.included_files = included_;
        out.origins = std::move(origins_);
        return out;
    }

    std::string RenderJson() {
        JsonMembers r;
        const int64_t spp = integrator_ == "mlt" && mlt_spp_ ? *mlt_spp_ : spp_;
        r.Add("width", std::to_string(std::clamp(width_, 1, 65536)))
            .Add("height", std::to_string(std::clamp(height_, 1, 65536)))
            .Add("spp", std::to_string(std::clamp<int64_t>(spp, 1, int64_t(1) << 24)))
            .Add("integrator", Quote(integrator_))
            .Add("max_depth", std::to_string(std::clamp(max_depth_, 0, 100000)));
        if (!sampler_.empty()) r.Add("sampler", Quote(sampler_));
        if (seed_ && *seed_ >= 0) r.Add("seed", std::to_string(*seed_));
        if (rr_threshold_ && *rr_threshold_ > 0) r.Add("rr_threshold", Num(*rr_threshold_));
        // Without a PixelFilter, pbrt-v4's default: a Gaussian of radius 1.5, sigma 0.5.
        r.Add("filter", filter_.empty()
                            ? "{\"type\": \"gaussian\", \"radius\": 1.5, \"sigma\": 0.5}"
                            : filter_);
        if (!mlt_.empty() && mlt_ != "{}") r.Add("mlt", mlt_);
        if (film_loc_) {
            origins_.emplace_back("/render/width", film_loc_->Str());
            origins_.emplace_back("/render/height", film_loc_->Str());
        }
        if (sampler_loc_) {
            origins_.emplace_back("/render/spp", sampler_loc_->Str());
            origins_.emplace_back("/render/seed", sampler_loc_->Str());
        }
        if (integrator_loc_) {
            for (const char* k :
                 {"/render/integrator", "/render/max_depth", "/render/mlt", "/render/rr_threshold"})
                origins_.emplace_back(k, integrator_loc_->Str());
        }
        if (filter_loc_) origins_.emplace_back("/render/filter", filter_loc_->Str());
        return r.Str();
    }

    std::string CameraJson() {
        const CameraState c = camera_.value_or(CameraState{});
        if (camera_) origins_.emplace_back("/camera", c.loc.Str());
        M4 world_from_camera = M4::Identity();
        Invert(c.camera_from_world, &world_from_camera);
        const M4 xf = world_ * world_from_camera;
        const V3 eye = xf.Point({}), forward = Normalized(xf.Vector({0, 0, 1}));
        V3 up = Normalized(xf.Vector({0, 1, 0}));
        if (!(Length(Cross(forward, up)) > 1e-6))
            up = std::abs(forward.y) < 0.9 ? V3{0, 1, 0} : V3{1, 0, 0};
        JsonMembers j;
        j.Add("eye", JsonVec(eye)).Add("target", JsonVec(eye + forward)).Add("up", JsonVec(up));
        j.Add("fov", Num(c.fov));
        if (c.lens_radius > 0) {
            j.Add("lens_radius", Num(c.lens_radius));
            j.Add("focus_distance", Num(c.focal_distance > 0 ? c.focal_distance : 1e6));
        }
        return j.Str();
    }

    struct WarningEntry {
        std::string where, what;
        int more = 0;
    };

    std::string shown_;
    const PbrtIncludeReader& read_include_;
    TokenStream in_;

    GraphicsState state_;
    std::vector<Saved> stack_;
    bool transforms_active_ = true;
    std::map<std::string, M4> named_coordinates_;
    bool in_world_ = false;
    bool mirror_decided_ = false;
    M4 world_ = M4::Identity();  // pbrt's world to Tessera's (a mirror, or the identity)

    std::optional<CameraState> camera_;
    int width_ = 1280, height_ = 720;
    int64_t spp_ = 16;
    std::optional<int64_t> mlt_spp_;
    std::string sampler_, integrator_ = "path", filter_, mlt_;
    int max_depth_ = 5;
    std::optional<int64_t> seed_;
    std::optional<double> rr_threshold_;
    std::optional<Loc> film_loc_, sampler_loc_, integrator_loc_, filter_loc_;

    std::map<std::string, std::pair<std::string, bool>> named_materials_;  // JSON name, surface
    std::map<std::string, SpectrumTexture> spectrum_textures_;
    std::map<std::string, std::optional<double>> float_textures_;
    std::map<std::string, std::shared_ptr<ObjectDef>> objects_;
    std::shared_ptr<ObjectDef> current_object_;
    Loc current_object_loc_;
    std::string default_material_;

    std::set<std::string> material_names_, textures_names_, object_names_;
    std::vector<std::pair<std::string, std::string>> textures_, materials_, object_json_;
    std::vector<std::string> shapes_, instances_, lights_;
    std::vector<std::pair<std::string, std::string>> origins_;
    std::vector<std::string> included_;
    std::vector<WarningEntry> warnings_;
    std::map<std::string, size_t> warning_index_;
};

}  // namespace

SceneError PbrtImport::Relocate(const SceneError& e) const {
    const std::string prefix = shown + ": ";
    const std::string& where = e.Where();
    if (where.rfind(prefix, 0) != 0) return e;
    const std::string pointer = where.substr(prefix.size());
    const std::pair<std::string, std::string>* best = nullptr;
    for (const auto& o : origins) {
        const bool inside = pointer == o.first || pointer.rfind(o.first + "/", 0) == 0;
        if (inside && (!best || o.first.size() > best->first.size())) best = &o;
    }
    if (!best) return e;
    std::string what = e.what();
    if (what.rfind(where + ": ", 0) == 0) what = what.substr(where.size() + 2);
    return SceneError(best->second, what + " (in the converted scene at " + pointer + ")");
}

bool IsPbrtFile(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".pbrt";
}

PbrtImport ImportPbrt(const std::string& shown, const std::string& text,
                      const PbrtIncludeReader& read_include) {
    return Converter(shown, read_include).Run(text);
}

PbrtImport ImportPbrt(const std::string& path) {
    constexpr uint64_t kMaxBytes = uint64_t(1) << 30;
    std::string text;
    try {
        text = ReadFileBytes(path, kMaxBytes, path);
    } catch (const std::runtime_error& e) {
        throw SceneError(path, std::string("scene file ") + e.what());
    }
    const fs::path dir = fs::path(path).parent_path();
    const PbrtIncludeReader read = [&](const std::string& written) {
        fs::path p(written);
        if (p.is_relative()) p = dir / p;
        return ReadFileBytes(p.lexically_normal().string(), kMaxBytes, written);
    };
    return ImportPbrt(path, text, read);
}

void LogPbrtWarnings(const PbrtImport& import) {
    static std::mutex mutex;
    static std::unordered_set<std::string> logged;
    std::lock_guard<std::mutex> lock(mutex);
    for (const std::string& w : import.warnings) {
        if (logged.size() < 100000 && !logged.insert(w).second) continue;
        spdlog::warn("{}", w);
    }
}

}  // namespace tessera

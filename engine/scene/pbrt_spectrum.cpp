// Spectra as RGB for the pbrt converter (scene/pbrt_spectrum.h).

#include "scene/pbrt_spectrum.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "scene/pbrt_json.h"

namespace tessera::pbrt {
namespace {

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

// pbrt-v4's named spectra that have an obvious RGB value; others become grey.
Rgb NamedSpectrum(const std::string& name, const Loc& loc, Rgb def, Warnings& warnings) {
    if (name == "stdillum-D65") return Rgb(1);
    if (name == "stdillum-A") return BlackbodyRgb(2856);  // A is a 2856 K black body
    for (const NamedGlass& g : kGlasses)
        if (name == g.name) return Rgb(float(g.eta));
    warnings.Add(loc, "spectrum \"" + name + "\" has no RGB equivalent here; the grey " +
                          JsonRgb(def) + " is used");
    return def;
}

}  // namespace

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

const std::set<std::string> kTesseraMetals = {"Ag", "Al", "Au", "Cr", "Cu"};

std::optional<std::pair<std::string, std::string>> MetalSpectrum(const std::string& name) {
    if (name.rfind("metal-", 0) == 0) {
        const size_t dash = name.rfind('-');
        if (dash > 6) return std::make_pair(name.substr(6, dash - 6), name.substr(dash + 1));
    }
    const std::string base = std::filesystem::path(name).filename().string();
    const size_t dot = base.find('.');
    if (base.size() > 4 && base.compare(base.size() - 4, 4, ".spd") == 0 &&
        dot != std::string::npos) {
        const std::string rest = base.substr(dot + 1, base.size() - 4 - dot - 1);
        if (rest == "eta" || rest == "k") return std::make_pair(base.substr(0, dot), rest);
    }
    return std::nullopt;
}

Param* GetColor(ParamSet& ps, const std::string& name) {
    return ps.Get(name, {"rgb", "spectrum", "blackbody", "xyz", "float"});
}

Rgb ColorOf(const Param& p, SpectrumKind kind, Rgb def, Warnings& warnings) {
    const std::vector<double>& v = p.numbers;
    if (p.type == "rgb") return Rgb(float(v[0]), float(v[1]), float(v[2]));
    if (p.type == "xyz") return ClampedRgb(XyzToLinearSrgb({v[0], v[1], v[2]}));
    if (p.type == "float") return v.empty() ? def : Rgb(float(v[0]));
    if (p.type == "blackbody") {
        if (v.empty()) return def;
        return BlackbodyRgb(v[0]) * float(v.size() >= 2 ? v[1] : 1.0);
    }
    if (!p.strings.empty()) return NamedSpectrum(p.strings[0], p.loc, def, warnings);
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

Rgb Color(ParamSet& ps, const std::string& name, SpectrumKind kind, Rgb def, Warnings& warnings) {
    const Param* p = GetColor(ps, name);
    return p ? ColorOf(*p, kind, def, warnings) : def;
}

}  // namespace tessera::pbrt

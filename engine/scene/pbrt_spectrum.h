#pragma once

// Spectra as RGB for the pbrt converter (scene/pbrt_import.h). pbrt-v4 renders spectrally;
// Tessera in linear sRGB. A colour parameter may be rgb, xyz, a black body, a constant, a
// named spectrum or (wavelength, value) pairs; each becomes one RGB triple, integrated
// against the CIE matching functions according to what the spectrum describes.

#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/color.h"
#include "scene/pbrt_parser.h"

namespace tessera::pbrt {

// What a sampled spectrum describes, which decides how it becomes RGB.
enum class SpectrumKind {
    kIlluminant,  // emission: its colour at luminance 1 (pbrt-v4 normalises lights)
    kAlbedo,      // a reflectance, lit by D65
    kUnbounded,   // any other quantity (eta, k, a scale): sampled at R, G and B
};

using SpectrumFn = std::function<double(double nm)>;

// A spectrum given as (wavelength, value) pairs, linear in between, constant beyond.
SpectrumFn PiecewiseLinear(const std::vector<double>& pairs);

// Refractive indices at the d line (587.6 nm) of the glasses pbrt-v4 names.
struct NamedGlass {
    const char* name;
    double eta;
};
inline constexpr NamedGlass kGlasses[] = {{"glass-BK7", 1.5168},   {"glass-BAF10", 1.6700},
                                          {"glass-FK51A", 1.4866}, {"glass-LASF9", 1.8503},
                                          {"glass-F5", 1.6727},    {"glass-F10", 1.7283},
                                          {"glass-F11", 1.7847}};

// The metals Tessera names (docs/scene-format.md, "metal").
extern const std::set<std::string> kTesseraMetals;

// The metal and quantity ("eta" or "k") a named spectrum or pbrt-v3 .spd file stands for:
// "metal-Au-eta", "spds/metals/Au.k.spd".
std::optional<std::pair<std::string, std::string>> MetalSpectrum(const std::string& name);

// A colour parameter, of any of the types that can give one; nullptr if none.
Param* GetColor(ParamSet& ps, const std::string& name);

// The colour of parameter `p`, of any spectral type; a named spectrum without an RGB
// equivalent gives `def` and a warning.
Rgb ColorOf(const Param& p, SpectrumKind kind, Rgb def, Warnings& warnings);

// The colour parameter `name` of `ps`; `def` when absent.
Rgb Color(ParamSet& ps, const std::string& name, SpectrumKind kind, Rgb def, Warnings& warnings);

}  // namespace tessera::pbrt

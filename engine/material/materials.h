#pragma once

// Factories for every built-in material and texture: the one place the scene builder
// creates them from. Parameters are validated by the builder before these are called.

#include <memory>
#include <string>

#include "material/material.h"
#include "material/microfacet.h"
#include "material/texture.h"

namespace tessera {

class MeasuredBrdfTable;  // material/measured_brdf.h
class FactoredBrdf;       // material/factored_brdf.h
class BrdfFitSampler;     // material/brdf_fit.h

using TextureRef = std::shared_ptr<const Texture>;

std::unique_ptr<Texture> MakeConstantTexture(Rgb value);
// Alternates `a` and `b` on a grid of `scale` checks per unit of uv.
std::unique_ptr<Texture> MakeCheckerboardTexture(Rgb a, Rgb b, Vec2 scale);
// Loads an image through OpenImageIO (bilinear lookup, uv wraps; v = 0 is the image's
// bottom row). Pixel values are taken as linear unless `srgb` is set. Throws
// std::runtime_error naming the file if it cannot be read.
std::unique_ptr<Texture> MakeImageTexture(const std::string& path, bool srgb);

// Lambertian reflector.
std::unique_ptr<Material> MakeDiffuseMaterial(TextureRef reflectance);
// Ideal specular reflector with a constant tint.
std::unique_ptr<Material> MakeMirrorMaterial(TextureRef reflectance);
// Ideal smooth dielectric (glass) with relative index of refraction `eta` (inside over
// outside); Fresnel-weighted choice of reflection and refraction on both sides.
std::unique_ptr<Material> MakeDielectricMaterial(float eta);
// Microfacet conductor; `eta`/`k` the complex index of refraction per channel. alpha is
// the distribution's roughness (alpha = perceptual roughness squared is the caller's
// job); below 1e-3 it is a smooth conductor. `specular` (values in [0, 1]) multiplies the
// Fresnel term; null means 1.
std::unique_ptr<Material> MakeRoughConductorMaterial(Rgb eta, Rgb k, float alpha_x, float alpha_y,
                                                     MicrofacetType type = MicrofacetType::kGgx,
                                                     TextureRef specular = nullptr);
// Microfacet dielectric (Walter et al. 2007), reflection and transmission.
std::unique_ptr<Material> MakeRoughDielectricMaterial(float eta, float alpha,
                                                      MicrofacetType type = MicrofacetType::kGgx);
// A diffuse base under a dielectric coat of index `eta` and microfacet roughness `alpha`
// (alpha = 0: a smooth coat).
std::unique_ptr<Material> MakePlasticMaterial(TextureRef diffuse, float eta, float alpha,
                                              MicrofacetType type = MicrofacetType::kGgx);
// A measured isotropic BRDF (a MERL table, or a resampled irregular measurement),
// reflecting alike on both sides; directions sampled through `factored` (built from the same
// table), or by the cosine when it is null.
std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                                               std::shared_ptr<const FactoredBrdf> factored);
// The same, directions sampled through an analytic fit of the table (a Lambertian term and a
// GGX lobe, MakeBrdfFitSampler); the fit only decides where to sample, f is the table's.
std::unique_ptr<Material> MakeMeasuredMaterial(std::shared_ptr<const MeasuredBrdfTable> table,
                                               std::shared_ptr<const BrdfFitSampler> fit);
// Fits the model to `table` and makes its sampler (FitBrdf; a fraction of a second).
std::shared_ptr<const BrdfFitSampler> MakeBrdfFitSampler(const MeasuredBrdfTable& table);
// A linear blend (1 - w) a + w b of two materials, w the channel average of `weight`
// (values in [0, 1]) at the surface point. `a` and `b` are not owned: they must outlive
// the blend (in a scene, both are the scene's materials too).
std::unique_ptr<Material> MakeBlendMaterial(const Material* a, const Material* b,
                                            TextureRef weight);

}  // namespace tessera

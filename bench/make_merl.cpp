// Writes a MERL .binary file of an analytic glossy BRDF, for the measured-BRDF benchmarks
// (MERL's own files are not redistributable): a Lambertian base under a GGX (Trowbridge-Reitz)
// lobe with height-correlated Smith masking and Schlick's Fresnel,
//     f = diffuse / pi + F(wi . h) D(h) G(wo, wi) / (4 cos(theta_o) cos(theta_i)),
//     F = f0 + (1 - f0) (1 - wi . h)^5,
// tabulated at the centres of MERL's cells (TabulateBrdf). The Fresnel term makes the lobe
// "GGX-ish": stronger towards grazing angles than the one-lobe fit of brdf_fit.h can follow.
//
//   make_merl OUT.binary [--alpha A] [--f0 R,G,B] [--diffuse R,G,B]
//
// Defaults: alpha 0.1, f0 0.95,0.64,0.54 (gold-like), diffuse 0.05,0.03,0.02.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <sstream>
#include <string>

#include "material/measured_brdf.h"

using namespace tessera;

namespace {

Rgb ParseRgb(const std::string& s) {
    std::istringstream in(s);
    Rgb c;
    char comma = 0;
    if (!(in >> c.r) || !(in >> comma) || comma != ',' || !(in >> c.g) || !(in >> comma) ||
        comma != ',' || !(in >> c.b) || !in.eof())
        throw std::invalid_argument("expected R,G,B, got '" + s + "'");
    return c;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argv[1][0] == '-') {
        std::fprintf(stderr,
                     "usage: make_merl OUT.binary [--alpha A] [--f0 R,G,B] [--diffuse R,G,B]\n");
        return 2;
    }
    try {
        const std::string out = argv[1];
        float alpha = 0.1f;
        Rgb f0(0.95f, 0.64f, 0.54f), diffuse(0.05f, 0.03f, 0.02f);
        for (int i = 2; i < argc; i += 2) {
            const std::string key = argv[i];
            if (i + 1 >= argc) throw std::invalid_argument(key + " needs a value");
            const std::string value = argv[i + 1];
            if (key == "--alpha")
                alpha = std::stof(value);
            else if (key == "--f0")
                f0 = ParseRgb(value);
            else if (key == "--diffuse")
                diffuse = ParseRgb(value);
            else
                throw std::invalid_argument("unknown option " + key);
        }
        if (!(alpha > 0 && alpha <= 1)) throw std::invalid_argument("alpha must be in (0, 1]");
        const float a2 = alpha * alpha;
        const MeasuredBrdfTable table = TabulateBrdf([&](const Vec3& wo, const Vec3& wi) {
            const Vec3 h = Normalize(wo + wi);
            const float d = a2 / (kPi * Sqr(h.z * h.z * (a2 - 1) + 1));
            auto lambda = [&](const Vec3& w) { return (std::sqrt(1 + a2 * Tan2Theta(w)) - 1) / 2; };
            const float g = 1 / (1 + lambda(wo) + lambda(wi));
            const float schlick = std::pow(1 - std::clamp(Dot(wi, h), 0.0f, 1.0f), 5.0f);
            const Rgb fresnel = f0 + (Rgb(1) - f0) * schlick;
            return diffuse * kInvPi + fresnel * (d * g / (4 * wo.z * wi.z));
        });
        WriteMerlBinary(out, table);
        std::printf("wrote %s: alpha %g, f0 %g,%g,%g, diffuse %g,%g,%g\n", out.c_str(), alpha, f0.r,
                    f0.g, f0.b, diffuse.r, diffuse.g, diffuse.b);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "make_merl: %s\n", e.what());
        return 1;
    }
    return 0;
}

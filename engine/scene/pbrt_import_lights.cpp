// The pbrt converter's lights (scene/pbrt_converter.h): point, spot, distant and infinite
// lights, and the area lights that shapes carry.

#include <algorithm>
#include <cmath>

#include "scene/pbrt_converter.h"

namespace tessera::pbrt {

Rgb Converter::LightScale(ParamSet& ps) {
    return Color(ps, "scale", SpectrumKind::kUnbounded, Rgb(1), warnings_);
}

void Converter::AddLight(const std::string& json, const Loc& loc) {
    origins_.emplace_back("/lights/" + std::to_string(lights_.size()), loc.Str());
    lights_.push_back(json);
}

void Converter::LightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                            const std::string& desc) {
    if (current_object_) {
        ps.MarkAllUsed();
        return Warn(loc, desc + ": lights inside an object definition are not supported; skipped");
    }
    DecideMirror();
    const M4 xf = world_ * state_.ctm;
    JsonMembers j;
    if (type == "point") {
        const Rgb i = Color(ps, "I", SpectrumKind::kIlluminant, Rgb(1), warnings_) * LightScale(ps);
        j.Add("type", Quote("point"))
            .Add("position", JsonVec(xf.Point(ps.Point("from", {}))))
            .Add("intensity", JsonRgb(i));
    } else if (type == "spot") {
        const Rgb i = Color(ps, "I", SpectrumKind::kIlluminant, Rgb(1), warnings_) * LightScale(ps);
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
        const Rgb l = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1), warnings_) * LightScale(ps);
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
bool Converter::InfiniteLight(JsonMembers& j, ParamSet& ps, const Loc& loc, const std::string& desc,
                              const M4& xf) {
    const bool has_l = ps.Has("L");
    const Rgb l = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1), warnings_);
    const Rgb scale = LightScale(ps);
    std::string file = ps.String("mapname");
    if (Param* f = ps.Get("filename", {"string"}); f && !f->strings.empty()) {
        file = f->strings[0];
        Warn(f->loc, desc + ": \"" + file +
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

void Converter::AreaLightSource(const Loc& loc, const std::string& type, ParamSet& ps,
                                const std::string& desc) {
    if (type != "diffuse") {
        ps.MarkAllUsed();
        state_.area_light.reset();
        return Warn(loc, desc + ": area light type \"" + type +
                             "\" is not supported; the "
                             "shapes that follow do not emit");
    }
    AreaLight a;
    a.radiance = Color(ps, "L", SpectrumKind::kIlluminant, Rgb(1), warnings_) * LightScale(ps);
    a.two_sided = ps.Bool("twosided", false);
    state_.area_light = a;
}

}  // namespace tessera::pbrt

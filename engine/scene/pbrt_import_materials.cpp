// The pbrt converter's textures and materials (scene/pbrt_converter.h): constant and image
// textures, and each pbrt material as the closest of Tessera's (docs/pbrt-import.md).

#include <algorithm>
#include <cmath>

#include "scene/pbrt_converter.h"

namespace tessera::pbrt {
namespace {

// pbrt-v3 remaps roughness to a microfacet alpha by a polynomial in log(roughness),
// pbrt-v4 by its square root.
double RoughnessToAlpha(double r, bool v3) {
    if (!v3) return std::sqrt(std::max(r, 0.0));
    const double x = std::log(std::max(r, 1e-3));
    return 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x +
           0.000640711 * x * x * x * x;
}

double ClampAlpha(double a) { return std::clamp(a, 0.001, 1.0); }

}  // namespace

// ---------------------------------------------------------------------------------------
// Textures, and the parameters that may name one

// A float parameter that may also be a (constant) float texture.
double Converter::FloatOrTexture(ParamSet& ps, const std::string& name, double def) {
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
std::string Converter::Reflectance(ParamSet& ps, const std::string& name, double def) {
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
        ClampAlbedo(ColorOf(*p, SpectrumKind::kAlbedo, Rgb(float(def)), warnings_), p->loc, name));
}

Rgb Converter::ClampAlbedo(Rgb c, const Loc& loc, const std::string& name) {
    const Rgb clamped(std::clamp(c.r, 0.0f, 1.0f), std::clamp(c.g, 0.0f, 1.0f),
                      std::clamp(c.b, 0.0f, 1.0f));
    if (!(clamped.r == c.r && clamped.g == c.g && clamped.b == c.b))
        Warn(loc, "\"" + name + "\" " + JsonRgb(c) +
                      " is clamped to [0, 1] (a reflectance above 1 creates energy)");
    return clamped;
}

void Converter::Texture(const Loc& loc, const std::string& name, const std::string& value_type,
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
            t.constant = Color(ps, "value", SpectrumKind::kAlbedo, Rgb(1), warnings_);
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
    ReportUnused(ps, desc, warnings_);
}

// ---------------------------------------------------------------------------------------
// Materials

// (alpha_u, alpha_v) from roughness, uroughness, vroughness and remaproughness.
std::pair<double, double> Converter::Alpha(ParamSet& ps, double def, bool v3) {
    const double r = FloatOrTexture(ps, "roughness", def);
    double u = FloatOrTexture(ps, "uroughness", r), v = FloatOrTexture(ps, "vroughness", r);
    // A roughness of 0 stays smooth (pbrt-v3's polynomial is not 0 there).
    if (ps.Bool("remaproughness", true)) {
        u = u > 0 ? RoughnessToAlpha(u, v3) : 0;
        v = v > 0 ? RoughnessToAlpha(v, v3) : 0;
    }
    return {u, v};
}

void Converter::AddAlphaTooHigh(const Loc& loc, double a) {
    if (a > 1) Warn(loc, "microfacet alpha " + Num(a) + " is clamped to 1");
}

// Conductor: Tessera's named metal when eta and k name one, else RGB eta and k.
void Converter::Conductor(JsonMembers& j, ParamSet& ps, const Loc& loc) {
    if (const Param* r = GetColor(ps, "reflectance")) {
        // pbrt-v4's artist-friendly conductor: eta = 1, k = 2 sqrt(r) / sqrt(1 - r).
        const Rgb c = ColorOf(*r, SpectrumKind::kAlbedo, Rgb(0.5f), warnings_);
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
        return ColorOf(*p, SpectrumKind::kUnbounded, def, warnings_);
    };
    j.Add("eta", JsonRgb(value(eta, Rgb(1.2f)))).Add("k", JsonRgb(value(k, Rgb(3.0f))));
}

// Dielectric index of refraction: a number, or a spectrum at 587.6 nm.
double Converter::Eta(ParamSet& ps, const std::string& name, double def) {
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
std::optional<std::string> Converter::ConvertMaterial(const std::string& type, ParamSet& ps,
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
                const Rgb c = Color(ps, key, SpectrumKind::kAlbedo, Rgb(1), warnings_);
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
            Color(ps, "Ks", SpectrumKind::kAlbedo, Rgb(0.25f), warnings_);
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
        Warn(loc,
             desc + ": material \"" + type + "\" is not supported; a diffuse " + refl + " is used");
        j.Add("type", Quote("diffuse")).Add("reflectance", refl);
    }
    return j.Str();
}

std::optional<std::string> Converter::MixMaterial(ParamSet& ps, const Loc& loc,
                                                  const std::string& desc) {
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

std::string Converter::AddMaterial(const std::string& base, const std::string& json,
                                   const Loc& loc) {
    const std::string name = UniqueName(material_names_, base);
    materials_.emplace_back(name, json);
    origins_.emplace_back("/materials/" + PointerKey(name), loc.Str());
    return name;
}

std::string Converter::DefaultMaterial() {
    if (default_material_.empty())
        default_material_ =
            AddMaterial("pbrt default",
                        JsonMembers().Add("type", Quote("diffuse")).Add("reflectance", "0.5").Str(),
                        Loc{std::make_shared<const std::string>(shown_), 1});
    return default_material_;
}

void Converter::Material(const Loc& loc, const std::string& type, ParamSet& ps,
                         const std::string& desc) {
    const std::optional<std::string> json = ConvertMaterial(type, ps, loc, desc);
    state_.surface = bool(json);
    state_.material = json ? AddMaterial(loc.Str(), *json, loc) : "";
}

void Converter::MakeNamedMaterial(const Loc& loc, const std::string& name, ParamSet& ps) {
    const std::string type = ps.String("type");
    const std::string desc = "MakeNamedMaterial \"" + name + "\" (\"" + type + "\")";
    if (type.empty()) Warn(loc, "MakeNamedMaterial \"" + name + "\" has no \"string type\"");
    if (named_materials_.count(name))
        Warn(loc, "MakeNamedMaterial: \"" + name + "\" is defined again; the new one applies");
    const std::optional<std::string> json = ConvertMaterial(type, ps, loc, desc);
    named_materials_[name] = {json ? AddMaterial(name, *json, loc) : "", bool(json)};
}

}  // namespace tessera::pbrt

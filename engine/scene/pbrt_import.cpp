// Conversion of pbrt-v4 and pbrt-v3 scene files into Tessera's JSON scene description
// (scene/pbrt_import.h; the subset: docs/pbrt-import.md). This file holds the entry points
// and the converter's core (scene/pbrt_converter.h): the directives, pbrt's graphics state
// (transforms, attribute stack, includes, the world's mirror), the rendering options and
// the converted scene. Materials, lights and shapes are converted in
// pbrt_import_{materials,lights,shapes}.cpp; tokens and parameter lists are read by
// pbrt_parser.h, colours by pbrt_spectrum.h.

#include "scene/pbrt_import.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <type_traits>
#include <unordered_set>

#include "io/file_bytes.h"
#include "scene/pbrt_converter.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

constexpr int kMaxIncludeDepth = 32;

}  // namespace

namespace pbrt {

PbrtImport Converter::Run(const std::string& text) {
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

// ---------------------------------------------------------------------------------------
// Positional arguments

double Converter::NumberArg(const Token& d) {
    const Token t = in_.Next(d.loc, "a number after " + d.text);
    double x;
    if (t.quoted || !ParseNumber(t.text, &x))
        SyntaxError(t.loc, d.text + ": expected a number, got '" + t.text + "'");
    return x;
}

// n numbers, bare or in brackets.
std::vector<double> Converter::NumberArgs(const Token& d, size_t n) {
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

std::string Converter::StringArg(const Token& d) {
    const Token t = in_.Next(d.loc, "a string after " + d.text);
    if (!t.quoted) SyntaxError(t.loc, d.text + ": expected a quoted string, got '" + t.text + "'");
    return t.text;
}

// ---------------------------------------------------------------------------------------
// Directives

void Converter::Directive(const Token& d) {
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
            SyntaxError(
                t.loc, "ActiveTransform: expected StartTime, EndTime or All, got '" + t.text + "'");
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
void Converter::DirectiveWithParams(const Token& d) {
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
    ReportUnused(ps, desc, warnings_);
}

// ---------------------------------------------------------------------------------------
// Transforms and the graphics state

// pbrt post-multiplies: the last transform given applies to the shape first.
void Converter::ApplyTransform(const M4& m, bool replace) {
    if (!transforms_active_) return;
    state_.ctm = replace ? m : state_.ctm * m;
}

void Converter::LookAt(const Token& d, const std::vector<double>& v) {
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

void Converter::PopState(const Token& d) {
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

void Converter::Include(const Token& d, const std::string& written) {
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
void Converter::DecideMirror() {
    if (mirror_decided_) return;
    mirror_decided_ = true;
    M4 world_from_camera = M4::Identity();
    if (camera_ && !Invert(camera_->camera_from_world, &world_from_camera))
        world_from_camera = M4::Identity();
    const V3 r = world_from_camera.Column(0), u = world_from_camera.Column(1),
             f = world_from_camera.Column(2);
    world_ = Dot(Cross(u, f), r) > 0 ? ScaleM({1, 1, -1}) : M4::Identity();
}

void Converter::WorldBegin(const Token& d) {
    if (in_world_) Warn(d.loc, "a second WorldBegin; ignored");
    in_world_ = true;
    DecideMirror();
    state_.ctm = M4::Identity();
    named_coordinates_["world"] = state_.ctm;
}

// ---------------------------------------------------------------------------------------
// Rendering options

void Converter::Camera(const Loc& loc, const std::string& type, ParamSet& ps) {
    CameraState c;
    c.camera_from_world = state_.ctm;
    c.loc = loc;
    M4 world_from_camera;
    if (Invert(state_.ctm, &world_from_camera)) named_coordinates_["camera"] = world_from_camera;
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

void Converter::Sampler(const Loc& loc, const std::string& type, ParamSet& ps) {
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

void Converter::Film(const Loc& loc, ParamSet& ps) {
    film_loc_ = loc;
    width_ = ps.Int("xresolution", 1280);
    height_ = ps.Int("yresolution", 720);
    if (ps.Get("filename", {"string"}))
        Warn(loc,
             "Film: \"filename\" is ignored: the output file is named on the command "
             "line (-o)");
}

void Converter::PixelFilter(const Loc& loc, const std::string& type, ParamSet& ps) {
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
        if (Param* a = ps.Get("alpha", {"float"}); a && !a->numbers.empty() && a->numbers[0] > 0)
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
        Warn(loc,
             "PixelFilter \"" + type + "\" is not supported; pbrt-v4's default Gaussian is used");
        return;
    }
    filter_ = f.Str();
}

void Converter::Integrator(const Loc& loc, const std::string& type, ParamSet& ps) {
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
        if (ps.Get("mutationsperpixel", {"integer"})) mlt_spp_ = ps.Int("mutationsperpixel", 100);
        if (ps.Get("bootstrapsamples", {"integer"}))
            m.Add("bootstrap_samples", std::to_string(ps.Int("bootstrapsamples", 100000)));
        if (ps.Get("chains", {"integer"})) m.Add("chains", std::to_string(ps.Int("chains", 1000)));
        if (ps.Get("largestepprobability", {"float"}))
            m.Add("p_large", Num(ps.Float("largestepprobability", 0.3)));
        mlt_ = m.Str();
    } else {
        integrator_ = "path";
        Warn(loc, "Integrator \"" + type + "\" is not supported; \"path\" is used");
    }
    if (ps.Get("rrthreshold", {"float"})) rr_threshold_ = ps.Float("rrthreshold", 1);
}

// ---------------------------------------------------------------------------------------
// The converted scene

PbrtImport Converter::Finish() {
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
    out.warnings = warnings_.Lines();
    out.included_files = included_;
    out.origins = std::move(origins_);
    return out;
}

std::string Converter::RenderJson() {
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
    r.Add("filter",
          filter_.empty() ? "{\"type\": \"gaussian\", \"radius\": 1.5, \"sigma\": 0.5}" : filter_);
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

std::string Converter::CameraJson() {
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

}  // namespace pbrt

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
    return pbrt::Converter(shown, read_include).Run(text);
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

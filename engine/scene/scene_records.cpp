// The scene file parser: JSON (through JsonValue) to checked SceneRecords. Each section
// has one function; each reads exactly the keys its record needs and then calls
// Finish(), so that any other key is reported as unknown, with the JSON pointer.

#include "scene/scene_records.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <stdexcept>

#include "core/error.h"
#include "io/file_bytes.h"
#include "scene/json_value.h"
#include "scene/pbrt_import.h"

namespace tessera {

const std::vector<std::string>& KnownIntegrators() {
    // Integrator::IntegratorNames() (integrator/integrator.h), which a test keeps equal.
    static const std::vector<std::string> kNames = {"path",  "direct", "photon", "irradiance-cache",
                                                    "light", "bdpt",   "mlt"};
    return kNames;
}

namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------
// Values

std::string Number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%g", v);
    return buf;
}

float Positive(const JsonValue& v) {
    float x = v.AsFloat();
    if (!(x > 0)) v.Fail("must be positive, got " + Number(x));
    return x;
}

float NonNegative(const JsonValue& v) {
    float x = v.AsFloat();
    if (x < 0) v.Fail("must not be negative, got " + Number(x));
    return x;
}

float InRange(const JsonValue& v, float lo, float hi, bool lo_open, bool hi_open) {
    float x = v.AsFloat();
    bool ok = (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
    if (!ok) {
        v.Fail("must be in " + std::string(lo_open ? "(" : "[") + Number(lo) + ", " + Number(hi) +
               (hi_open ? ")" : "]") + ", got " + Number(x));
    }
    return x;
}

Rgb NonNegativeRgb(const JsonValue& v) {
    Rgb c = v.AsRgb();
    if (c.r < 0 || c.g < 0 || c.b < 0) v.Fail("colour components must not be negative");
    return c;
}

Vec3 NonZeroVec3(const JsonValue& v) {
    Vec3 d = v.AsVec3();
    if (LengthSquared(d) == 0) v.Fail("must not be the zero vector");
    return d;
}

// The index of v's string among `names`; `what` ("shape type") names the list.
int ParseEnum(const JsonValue& v, const std::vector<std::string>& names, const std::string& what) {
    std::string s = v.AsString();
    for (size_t i = 0; i < names.size(); ++i)
        if (names[i] == s) return int(i);
    std::string near = ClosestMatch(s, names);
    v.Fail("unknown " + what + " '" + s + "'" +
           (near.empty() ? "" : " (did you mean '" + near + "'?)") + "; expected " +
           JoinAlternatives(names));
}

// The index of the record named v's string, from a name-to-index map.
int ParseReference(const JsonValue& v, const std::map<std::string, int>& names,
                   const std::string& what) {
    std::string s = v.AsString();
    auto it = names.find(s);
    if (it != names.end()) return it->second;
    std::vector<std::string> known;
    for (const auto& [name, index] : names) known.push_back(name);
    std::string near = ClosestMatch(s, known);
    if (!near.empty()) v.Fail("unknown " + what + " '" + s + "' (did you mean '" + near + "'?)");
    v.Fail("unknown " + what + " '" + s + "'" +
           (known.empty() ? " (none is defined)" : "; defined: " + JoinAlternatives(known)));
}

// ---------------------------------------------------------------------------------------
// Context shared by the section parsers

// Whether `p` opens for reading. Without blocking: a file replaced by a FIFO after it was
// checked must not hang the parser.
bool CanOpen(const fs::path& p) {
    const int fd = ::open(p.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return false;
    ::close(fd);
    return true;
}

// Why the file `rel` (relative to the bundle `root`) may not be read as part of the
// bundle; empty if it may. Each component is checked without following links, so that
// a link cannot lead outside the bundle; only regular files (no devices, FIFOs or
// folders, which a reader could block on or read forever) of at most `max_bytes`.
std::string CheckBundleFile(const fs::path& root, const fs::path& rel, uint64_t max_bytes) {
    fs::path p = root;
    fs::file_status st;
    std::error_code ec;
    for (const fs::path& part : rel) {
        if (part.empty() || part == ".") continue;
        if (p != root && !fs::is_directory(st)) return "does not exist in the bundle";
        p /= part;
        st = fs::symlink_status(p, ec);
        if (ec || !fs::exists(st)) return "does not exist in the bundle";
        if (fs::is_symlink(st))
            return "is or passes through a symbolic link; a bundle holds only regular files";
    }
    if (!fs::is_regular_file(st)) return "is not a regular file";
    const uintmax_t size = fs::file_size(p, ec);
    if (ec) return "cannot be read";
    if (size > max_bytes)
        return "is " + std::to_string(size) + " bytes, over the limit of " +
               std::to_string(max_bytes);
    if (!CanOpen(p)) return "cannot be read";
    return {};
}

// Whether a reference as written may name a file of the bundle: relative, without "..".
// Decided on the text alone, so that the answer says nothing about the machine's files.
bool StaysInBundle(const std::string& given) {
    fs::path p(given);
    if (p.is_absolute() || p.has_root_name() || p.has_root_directory()) return false;
    for (const fs::path& part : p)
        if (part == "..") return false;
    return true;
}

struct Context {
    fs::path base_dir;
    // Set when sandboxed (SceneLoadOptions): the bundle root, and the scene's folder
    // relative to it.
    fs::path sandbox_root, scene_dir_in_bundle;
    uint64_t max_file_bytes = 0;
    std::map<std::string, int> textures, materials, objects;
    double fps = 24;  // the "animation" section's, for keys given by frame
    // Files referenced so far, as (section, as written, resolved).
    struct FileRef {
        std::string section, written, resolved;
    };
    mutable std::vector<FileRef> files;
    std::string section;  // the top-level key being parsed

    // A file the scene refers to, resolved against the scene's folder; must be a readable
    // regular file. The only place where the parser looks at the file system.
    std::string ResolveFile(const JsonValue& v, const std::string& what) const {
        std::string given = v.AsString();
        if (given.empty()) v.Fail("empty file name");
        const std::string shown = what + " '" + given + "'";
        std::string resolved;
        if (!sandbox_root.empty()) {
            if (!StaysInBundle(given))
                v.Fail(shown +
                       " is not in the scene's bundle: a bundle's scene may refer only to "
                       "relative paths without '..'");
            fs::path rel = (scene_dir_in_bundle / given).lexically_normal();
            if (std::string why = CheckBundleFile(sandbox_root, rel, max_file_bytes); !why.empty())
                v.Fail(shown + " " + why);
            resolved = (sandbox_root / rel).string();
        } else {
            fs::path p(given);
            if (p.is_relative()) p = base_dir / p;
            p = p.lexically_normal();
            resolved = p.string();
            const std::string at =
                given == resolved ? shown : shown + " (resolved to '" + resolved + "')";
            std::error_code ec;
            if (!fs::exists(p, ec)) v.Fail(at + " does not exist");
            if (fs::is_directory(p, ec)) v.Fail(at + " is a directory");
            // Before opening: opening a FIFO blocks, and a device can be read forever.
            if (!fs::is_regular_file(p, ec)) v.Fail(at + " is not a regular file");
            const uintmax_t size = fs::file_size(p, ec);
            if (!ec && size > max_file_bytes)
                v.Fail(at + " is " + std::to_string(size) + " bytes, over the limit of " +
                       std::to_string(max_file_bytes));
            if (!CanOpen(p)) v.Fail("cannot read " + at);
        }
        files.push_back({section, given, resolved});
        return resolved;
    }

    // The bytes of a file that the scene file includes (pbrt's Include), named as
    // written, under the same rules as ResolveFile's. Throws std::runtime_error saying why
    // it cannot be read.
    std::string ReadIncluded(const std::string& given) const {
        if (given.empty()) throw std::runtime_error("empty file name");
        if (!sandbox_root.empty()) {
            if (!StaysInBundle(given))
                throw std::runtime_error(
                    "not in the scene's bundle: a bundle's scene may refer only to relative "
                    "paths without '..'");
            fs::path rel = (scene_dir_in_bundle / given).lexically_normal();
            if (std::string why = CheckBundleFile(sandbox_root, rel, max_file_bytes); !why.empty())
                throw std::runtime_error(why);
            return ReadFileBelow(sandbox_root.string(), rel.string(), max_file_bytes);
        }
        fs::path p(given);
        if (p.is_relative()) p = base_dir / p;
        return ReadFileBytes(p.lexically_normal().string(), max_file_bytes, given);
    }
};

// ---------------------------------------------------------------------------------------
// render

FilterSettings ParseFilter(const JsonValue& v) {
    JsonObject o = v.AsObject();
    FilterSettings f;
    static const std::vector<std::string> kTypes = {"box", "gaussian", "mitchell", "tent"};
    int type = ParseEnum(o.Required("type"), kTypes, "filter type");
    f.type = *ParseFilterType(kTypes[type]);
    if (auto r = o.Get("radius")) f.radius = Positive(*r);
    if (auto m = o.Get("sampling"))
        f.sampling = ParseEnum(*m, {"splat", "importance"}, "filter sampling") == 0
                         ? FilterSampling::kSplat
                         : FilterSampling::kImportance;
    if (f.type == FilterType::kGaussian) {
        if (auto s = o.Get("sigma")) f.gaussian_sigma = Positive(*s);
    }
    if (f.type == FilterType::kMitchell) {
        if (auto b = o.Get("b")) f.mitchell_b = b->AsFloat();
        if (auto c = o.Get("c")) f.mitchell_c = c->AsFloat();
    }
    o.Finish("a " + kTypes[type] + " filter");
    return f;
}

PhotonOptions ParsePhoton(const JsonValue& v) {
    JsonObject o = v.AsObject();
    PhotonOptions p;
    if (auto n = o.Get("global_photons")) p.global_photons = int(n->AsInt(0, 1 << 30));
    if (auto n = o.Get("caustic_photons")) p.caustic_photons = int(n->AsInt(0, 1 << 30));
    if (auto n = o.Get("batches")) p.batches = int(n->AsInt(1, 4096));
    if (auto b = o.Get("global_direct")) p.global_direct = b->AsBool();
    if (auto n = o.Get("global_lookup")) p.global_lookup = int(n->AsInt(1, 10000));
    if (auto n = o.Get("caustic_lookup")) p.caustic_lookup = int(n->AsInt(1, 10000));
    if (auto r = o.Get("max_radius")) p.max_radius = Positive(*r);
    if (auto n = o.Get("gather_rays")) p.gather_rays = int(n->AsInt(1, 65536));
    o.Finish("the photon block");
    return p;
}

IrradianceOptions ParseIrradianceCache(const JsonValue& v) {
    JsonObject o = v.AsObject();
    IrradianceOptions c;
    if (auto b = o.Get("enabled")) c.enabled = b->AsBool();
    if (auto a = o.Get("accuracy")) c.accuracy = Positive(*a);
    if (auto n = o.Get("hemisphere_samples")) c.hemisphere_samples = int(n->AsInt(4, 1 << 20));
    if (auto r = o.Get("min_radius")) c.min_radius = Positive(*r);
    if (auto r = o.Get("max_radius")) c.max_radius = Positive(*r);
    if (auto n = o.Get("passes")) c.passes = int(n->AsInt(0, 8));
    if (auto b = o.Get("gradients")) c.gradients = b->AsBool();
    o.Finish("the irradiance_cache block");
    return c;
}

MltOptions ParseMlt(const JsonValue& v) {
    JsonObject o = v.AsObject();
    MltOptions m;
    if (auto n = o.Get("bootstrap_samples")) m.bootstrap_samples = int(n->AsInt(1, 1 << 30));
    if (auto n = o.Get("chains")) m.chains = int(n->AsInt(1, 1 << 20));
    if (auto p = o.Get("p_large")) m.p_large = InRange(*p, 0, 1, true, false);
    o.Finish("the mlt block");
    return m;
}

RenderSettings ParseRender(const JsonValue& v) {
    JsonObject o = v.AsObject();
    RenderSettings r;
    if (auto w = o.Get("width")) r.resolution.x = int(w->AsInt(1, 65536));
    if (auto h = o.Get("height")) r.resolution.y = int(h->AsInt(1, 65536));
    if (auto s = o.Get("spp")) r.spp = int(s->AsInt(1, 1 << 24));
    if (auto i = o.Get("integrator"))
        r.integrator = KnownIntegrators()[ParseEnum(*i, KnownIntegrators(), "integrator")];
    if (auto d = o.Get("max_depth")) r.max_depth = int(d->AsInt(0, 100000));
    if (auto d = o.Get("rr_depth")) r.rr_depth = int(d->AsInt(0, 100000));
    if (auto t = o.Get("rr_threshold")) r.rr_threshold = Positive(*t);
    if (auto s = o.Get("sampler")) {
        const std::vector<std::string>& names = SamplerTypeNames();
        r.sampler = *ParseSamplerType(names[ParseEnum(*s, names, "sampler")]);
    }
    if (auto t = o.Get("time_sampler")) {
        std::vector<std::string> names;
        for (TimeSampler s : kTimeSamplers) names.push_back(TimeSamplerName(s));
        r.time_sampler = kTimeSamplers[ParseEnum(*t, names, "time sampler")];
    }
    if (auto s = o.Get("seed")) r.seed = s->AsUint64();
    if (auto t = o.Get("tile_size")) r.tile_size = int(t->AsInt(1, 65536));
    if (auto t = o.Get("light_paths_per_task")) r.light_paths_per_task = int(t->AsInt(1, 1 << 30));
    if (auto f = o.Get("frame")) r.frame = int(f->AsInt(0, 1 << 30));
    if (auto f = o.Get("filter")) r.filter = ParseFilter(*f);
    if (auto t = o.Get("transparent")) r.transparent = t->AsBool();
    if (auto p = o.Get("photon")) r.photon = ParsePhoton(*p);
    if (auto c = o.Get("irradiance_cache")) r.irradiance = ParseIrradianceCache(*c);
    if (auto m = o.Get("mlt")) r.mlt = ParseMlt(*m);
    if (auto d = o.Get("debug")) {
        int t = ParseEnum(*d, {"none", "photons", "records", "indirect"}, "debug view");
        r.debug = static_cast<DebugView>(t);
    }
    o.Finish("the render block");
    return r;
}

// ---------------------------------------------------------------------------------------
// transforms

Transform ParseLookAt(const JsonValue& v) {
    JsonObject o = v.AsObject();
    Vec3 eye = o.Required("eye").AsVec3();
    Vec3 target = o.Required("target").AsVec3();
    Vec3 up(0, 1, 0);
    if (auto u = o.Get("up")) up = NonZeroVec3(*u);
    o.Finish("look_at");
    try {
        return Transform::LookAt(eye, target, up);
    } catch (const std::invalid_argument& e) {
        v.Fail(e.what());
    }
}

Transform ParseMatrix(const JsonValue& v) {
    std::vector<float> a = v.AsFloats(16);
    Mat4 m;
    for (int i = 0; i < 16; ++i) m.m[i / 4][i % 4] = a[i];
    if (m.m[3][0] != 0 || m.m[3][1] != 0 || m.m[3][2] != 0 || m.m[3][3] != 1)
        v.Fail("the last row of a matrix must be 0 0 0 1 (affine transforms only)");
    Mat4 inv;
    if (!Inverse(m, &inv)) v.Fail("matrix is singular");
    return Transform(m, inv);
}

// One step: an object with translate, rotate and/or scale (applied as scale, then rotate,
// then translate), or with matrix or look_at alone.
Transform ParseTransformStep(const JsonValue& v) {
    JsonObject o = v.AsObject();
    auto matrix = o.Get("matrix"), look_at = o.Get("look_at");
    auto translate = o.Get("translate"), rotate = o.Get("rotate"), scale = o.Get("scale");
    o.Finish("a transform");
    int count = int(bool(matrix)) + bool(look_at) + bool(translate) + bool(rotate) + bool(scale);
    if (count == 0) v.Fail("empty transform: expected translate, rotate, scale, matrix or look_at");
    if ((matrix || look_at) && count > 1) {
        v.Fail("'" + std::string(matrix ? "matrix" : "look_at") +
               "' cannot be combined with other operations in one object; list the steps");
    }
    if (matrix) return ParseMatrix(*matrix);
    if (look_at) return ParseLookAt(*look_at);
    Transform xf;
    if (scale) {
        Vec3 s = scale->IsNumber() ? Vec3(scale->AsFloat(), scale->AsFloat(), scale->AsFloat())
                                   : scale->AsVec3();
        if (s.x == 0 || s.y == 0 || s.z == 0) scale->Fail("scale factors must not be zero");
        xf = Transform::Scale(s);
    }
    if (rotate) {
        JsonObject r = rotate->AsObject();
        Vec3 axis = NonZeroVec3(r.Required("axis"));
        float angle = r.Required("angle").AsFloat();
        r.Finish("rotate");
        xf = Transform::Rotate(angle, axis) * xf;
    }
    if (translate) xf = Transform::Translate(translate->AsVec3()) * xf;
    return xf;
}

// An object (one step) or a list of steps, the first applied first.
Transform ParseTransform(const JsonValue& v) {
    if (v.IsObject()) return ParseTransformStep(v);
    if (!v.IsArray())
        v.Fail("expected a transform (an object or a list of objects), got " + v.KindName());
    Transform xf;
    for (const JsonValue& step : v.Elements()) xf = ParseTransformStep(step) * xf;
    return xf;
}

// ---------------------------------------------------------------------------------------
// animation

// The "animation" section: {"fps": 24, "frames": [first, last]} (or "frames": "A-B").
AnimationSettings ParseAnimationSettings(const JsonValue& v) {
    JsonObject o = v.AsObject();
    AnimationSettings a;
    if (auto f = o.Get("fps")) {
        a.fps = f->AsDouble();
        if (!(a.fps > 0) || !std::isfinite(a.fps) || a.fps > 100000)
            f->Fail("fps must be positive and at most 100000, got " + Number(a.fps));
    }
    if (auto f = o.Get("frames")) {
        if (f->IsString()) {
            const std::string text = f->AsString();
            int first = 0, last = 0;
            char extra = 0;
            const int n = std::sscanf(text.c_str(), "%d-%d%c", &first, &last, &extra);
            if (n == 1)
                last = first;
            else if (n != 2)
                f->Fail("expected \"A-B\" or [A, B], got \"" + text + "\"");
            a.frame_start = first;
            a.frame_end = last;
        } else {
            if (!f->IsArray() || f->Size() != 2)
                f->Fail("expected [first, last] or \"A-B\", got " + f->KindName());
            std::vector<JsonValue> ends = f->Elements();
            a.frame_start = int(ends[0].AsInt(0, 1 << 30));
            a.frame_end = int(ends[1].AsInt(0, 1 << 30));
        }
        if (a.frame_start < 0 || a.frame_end < a.frame_start)
            f->Fail("frames must run from a first frame >= 0 to a last frame >= the first");
    }
    o.Finish("the animation section");
    return a;
}

// A key's time in seconds: "time" (seconds) or "frame" (a frame number, fractions
// allowed), not both.
double ParseKeyTime(JsonObject& k, const JsonValue& key, double fps) {
    auto t = k.Get("time"), f = k.Get("frame");
    if (t && f) f->Fail("give either time (seconds) or frame, not both");
    if (!t && !f) key.Fail("a key needs a time (seconds) or a frame");
    const JsonValue& v = t ? *t : *f;
    const double value = v.AsDouble();
    if (!std::isfinite(value)) v.Fail("must be finite");
    return t ? value : value / fps;
}

Interpolation ParseInterpolationKey(JsonObject& o) {
    auto i = o.Get("interpolation");
    if (!i) return Interpolation::kLinear;
    const std::vector<std::string> names = {"linear", "catmull-rom", "bezier"};
    return *ParseInterpolation(names[ParseEnum(*i, names, "interpolation")]);
}

// The keys' times must increase; names the first key that does not.
void CheckKeyOrder(const std::vector<double>& times, const std::vector<JsonValue>& keys) {
    for (size_t i = 1; i < times.size(); ++i)
        if (!(times[i] > times[i - 1]))
            keys[i].Fail("keys out of order: this key's time (" + Number(times[i]) +
                         " s) is not after the previous key's (" + Number(times[i - 1]) + " s)");
}

// The "keys" of an animation object `o` (whose other keys are read already): a
// non-empty array. Finishes `o` as `what`.
std::vector<JsonValue> AnimationKeys(JsonObject& o, const std::string& what) {
    JsonValue keys_v = o.Required("keys");
    o.Finish(what);
    if (!keys_v.IsArray() || keys_v.Size() == 0)
        keys_v.Fail("expected a non-empty array of keys, got " +
                    (keys_v.IsArray() ? std::string("an empty array") : keys_v.KindName()));
    return keys_v.Elements();
}

// {"interpolation": ..., "keys": [{"time" | "frame", "translate", "rotate": {"axis",
// "angle"}, "scale"}, ...]}: each key a whole pose (absent parts: identity).
AnimatedTransform ParseAnimation(const JsonValue& v, double fps) {
    JsonObject o = v.AsObject();
    const Interpolation interp = ParseInterpolationKey(o);
    std::vector<JsonValue> elements = AnimationKeys(o, "an animation");
    std::vector<TransformKey> keys;
    std::vector<double> times;
    for (const JsonValue& kv : elements) {
        JsonObject k = kv.AsObject();
        TransformKey key;
        key.time = ParseKeyTime(k, kv, fps);
        if (auto t = k.Get("translate")) key.translate = t->AsVec3();
        if (auto r = k.Get("rotate")) {
            JsonObject ro = r->AsObject();
            Vec3 axis = NonZeroVec3(ro.Required("axis"));
            float angle = ro.Required("angle").AsFloat();
            ro.Finish("rotate");
            key.rotate = QuaternionFromAxisAngle(axis, angle);
        }
        if (auto sc = k.Get("scale")) {
            key.scale =
                sc->IsNumber() ? Vec3(sc->AsFloat(), sc->AsFloat(), sc->AsFloat()) : sc->AsVec3();
            if (!(key.scale.x > 0 && key.scale.y > 0 && key.scale.z > 0))
                sc->Fail("animated scale factors must be positive");
        }
        k.Finish("an animation key");
        times.push_back(key.time);
        keys.push_back(key);
    }
    CheckKeyOrder(times, elements);
    try {
        return AnimatedTransform(std::move(keys), interp);
    } catch (const std::invalid_argument& e) {
        v.Fail(e.what());
    }
}

// The camera's "animation": keys of eye, target, up, fov and focus_distance; a key's
// missing values are the camera's own.
CameraTrack ParseCameraAnimation(const JsonValue& v, const CameraKey& base, double fps) {
    JsonObject o = v.AsObject();
    const Interpolation interp = ParseInterpolationKey(o);
    std::vector<JsonValue> elements = AnimationKeys(o, "a camera animation");
    std::vector<CameraKey> keys;
    std::vector<double> times;
    for (const JsonValue& kv : elements) {
        JsonObject k = kv.AsObject();
        CameraKey key = base;
        key.time = ParseKeyTime(k, kv, fps);
        if (auto e = k.Get("eye")) key.eye = e->AsVec3();
        if (auto t = k.Get("target")) key.target = t->AsVec3();
        if (auto u = k.Get("up")) key.up = NonZeroVec3(*u);
        if (auto f = k.Get("fov")) key.fov_deg = InRange(*f, 0, 180, true, true);
        if (auto f = k.Get("focus_distance")) key.focus_distance = Positive(*f);
        k.Finish("a camera key");
        if (key.eye == key.target) kv.Fail("target must differ from eye");
        if (LengthSquared(Cross(Normalize(key.target - key.eye), Normalize(key.up))) < 1e-10f)
            kv.Fail("up is parallel to the view direction");
        times.push_back(key.time);
        keys.push_back(key);
    }
    CheckKeyOrder(times, elements);
    try {
        return CameraTrack(std::move(keys), interp);
    } catch (const std::invalid_argument& e) {
        v.Fail(e.what());
    }
}

// ---------------------------------------------------------------------------------------
// camera

CameraRecord ParseCamera(const JsonValue& v, double fps) {
    JsonObject o = v.AsObject();
    CameraRecord c;
    c.where = v.Where();
    if (auto t = o.Get("type")) ParseEnum(*t, {"perspective"}, "camera type");
    JsonValue eye_v = o.Required("eye");
    Vec3 eye = eye_v.AsVec3();
    JsonValue target_v = o.Required("target");
    Vec3 target = target_v.AsVec3();
    if (eye == target) target_v.Fail("target must differ from eye");
    Vec3 up(0, 1, 0);
    auto up_v = o.Get("up");
    if (up_v) up = NonZeroVec3(*up_v);
    if (LengthSquared(Cross(Normalize(target - eye), Normalize(up))) < 1e-10f)
        (up_v ? *up_v : v).Fail("up is parallel to the view direction");
    c.camera_to_world = Transform::LookAt(eye, target, up);
    if (auto f = o.Get("fov")) c.fov_deg = InRange(*f, 0, 180, true, true);
    auto lens = o.Get("lens_radius"), aperture = o.Get("aperture");
    if (lens && aperture) aperture->Fail("give either lens_radius or aperture, not both");
    if (lens) c.lens_radius = NonNegative(*lens);
    if (aperture) c.lens_radius = NonNegative(*aperture) / 2;
    c.focus_distance = Distance(eye, target);
    if (auto f = o.Get("focus_distance")) c.focus_distance = Positive(*f);
    if (auto s = o.Get("shutter")) {
        std::vector<float> t = s->AsFloats(2);
        if (!(t[0] >= 0 && t[1] <= 1))
            s->Fail(
                "shutter times are fractions of a frame, within [0, 1] (0.5: a 180 degree "
                "shutter), got [" +
                Number(t[0]) + ", " + Number(t[1]) + "]");
        if (t[1] < t[0]) s->Fail("shutter closes before it opens");
        c.shutter_open = t[0];
        c.shutter_close = t[1];
    }
    if (auto a = o.Get("animation")) {
        CameraKey base;
        base.time = 0;
        base.eye = eye;
        base.target = target;
        base.up = up;
        base.fov_deg = c.fov_deg;
        base.focus_distance = c.focus_distance;
        c.track = ParseCameraAnimation(*a, base, fps);
    }
    o.Finish("a perspective camera");
    return c;
}

// ---------------------------------------------------------------------------------------
// textures and materials

const std::vector<std::string> kTextureTypes = {"constant", "checkerboard", "image"};

TextureRecord ParseTexture(const std::string& name, const JsonValue& v, const Context& ctx) {
    JsonObject o = v.AsObject();
    TextureRecord t;
    t.name = name;
    t.where = v.Where();
    int type = ParseEnum(o.Required("type"), kTextureTypes, "texture type");
    t.kind = TextureKind(type);
    switch (t.kind) {
        case TextureKind::kConstant:
            t.value = NonNegativeRgb(o.Required("value"));
            break;
        case TextureKind::kCheckerboard: {
            t.a = NonNegativeRgb(o.Required("a"));
            t.b = NonNegativeRgb(o.Required("b"));
            if (auto s = o.Get("scale")) {
                t.scale = s->AsVec2();
                if (!(t.scale.x > 0 && t.scale.y > 0)) s->Fail("scale must be positive");
            }
            break;
        }
        case TextureKind::kImage: {
            JsonValue file = o.Required("file");
            t.path = ctx.ResolveFile(file, "image file");
            t.path_where = file.Where();
            // 8-bit formats are almost always sRGB-encoded; float formats are linear.
            std::string ext = fs::path(t.path).extension().string();
            for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
            t.srgb = ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" ||
                     ext == ".tga" || ext == ".gif";
            if (auto s = o.Get("srgb")) t.srgb = s->AsBool();
            break;
        }
    }
    o.Finish("a " + kTextureTypes[type] + " texture");
    return t;
}

// A reflectance: an RGB array, a number, or a texture name. `bounded` reflectances
// (albedos) must not exceed 1, or the surface would create energy.
ColorParam ParseReflectance(const JsonValue& v, const Context& ctx, bool bounded) {
    ColorParam p;
    p.where = v.Where();
    if (v.IsString()) {
        p.texture = ParseReference(v, ctx.textures, "texture");
        return p;
    }
    if (!v.IsNumber() && !v.IsArray())
        v.Fail("expected an RGB colour, a number or a texture name, got " + v.KindName());
    p.value = NonNegativeRgb(v);
    if (bounded && p.value.MaxComponent() > 1) {
        v.Fail("albedo " + Number(p.value.MaxComponent()) +
               " exceeds 1 (a reflectance above 1 creates energy)");
    }
    return p;
}

struct Metal {
    const char* name;
    Rgb eta, k;
};

// RGB fits of measured complex indices of refraction (as tabulated by Mitsuba and
// Tungsten from the same spectral data).
const Metal kMetals[] = {
    {"Ag", {0.155265f, 0.116723f, 0.138381f}, {4.828343f, 3.122246f, 2.146950f}},
    {"Al", {1.657460f, 0.880369f, 0.521229f}, {9.223869f, 6.269523f, 4.837001f}},
    {"Au", {0.143119f, 0.374957f, 1.442479f}, {3.983160f, 2.385721f, 1.603215f}},
    {"Cr", {4.369683f, 2.916702f, 1.654701f}, {5.206434f, 4.231365f, 3.754947f}},
    {"Cu", {0.200438f, 0.924033f, 1.102212f}, {3.912949f, 2.452848f, 2.142188f}},
};

// GGX alpha from "alpha", or from "alpha_u" and "alpha_v" together.
void ParseAlpha(JsonObject& o, MaterialRecord* m, float default_alpha, bool allow_zero,
                bool anisotropic) {
    auto read = [&](const JsonValue& v) { return InRange(v, 0, 1, !allow_zero, false); };
    auto alpha = o.Get("alpha");
    std::optional<JsonValue> au, av;
    if (anisotropic) {
        au = o.Get("alpha_u");
        av = o.Get("alpha_v");
    }
    if (alpha && (au || av)) (au ? *au : *av).Fail("give either alpha or alpha_u and alpha_v");
    if (bool(au) != bool(av))
        o.Fail(std::string("give both alpha_u and alpha_v (only ") + (au ? "alpha_u" : "alpha_v") +
               " is given)");
    m->alpha_u = m->alpha_v = alpha ? read(*alpha) : default_alpha;
    if (au) {
        m->alpha_u = read(*au);
        m->alpha_v = read(*av);
    }
}

// In MaterialKind's order.
const std::vector<std::string> kMaterialTypes = {"diffuse",        "mirror",          "dielectric",
                                                 "roughconductor", "roughdielectric", "plastic",
                                                 "conductor",      "blend",           "measured"};

float ParseEta(JsonObject& o) {
    auto e = o.Get("eta");
    if (!e) return 1.5f;
    float eta = Positive(*e);
    if (eta == 1) e->Fail("eta 1 makes an invisible interface");
    return eta;
}

// Materials given inline in blends: appended after the `first` named ones.
struct InlineMaterials {
    int first = 0;
    std::vector<MaterialRecord> records;
};

void ParseDistribution(JsonObject& o, MaterialRecord* m) {
    if (auto d = o.Get("distribution"))
        m->distribution = MicrofacetType(ParseEnum(*d, {"ggx", "beckmann"}, "distribution"));
}

MaterialRecord ParseMaterial(const std::string& name, const JsonValue& v, const Context& ctx,
                             InlineMaterials* inline_materials);

// A blend's part: a material name or an inline material record.
int ParseBlendPart(const JsonValue& v, const Context& ctx, InlineMaterials* inline_materials) {
    if (v.IsString()) return ParseReference(v, ctx.materials, "material");
    if (!v.IsObject()) v.Fail("expected a material name or a material record, got " + v.KindName());
    MaterialRecord part = ParseMaterial("", v, ctx, inline_materials);
    inline_materials->records.push_back(std::move(part));
    return inline_materials->first + int(inline_materials->records.size()) - 1;
}

MaterialRecord ParseMaterial(const std::string& name, const JsonValue& v, const Context& ctx,
                             InlineMaterials* inline_materials) {
    JsonObject o = v.AsObject();
    MaterialRecord m;
    m.name = name;
    m.where = v.Where();
    int type = ParseEnum(o.Required("type"), kMaterialTypes, "material type");
    m.kind = MaterialKind(type);
    auto reflectance = [&](float def) {
        if (auto r = o.Get("reflectance")) return ParseReflectance(*r, ctx, true);
        ColorParam p;
        p.where = v.Where();
        p.value = Rgb(def);
        return p;
    };
    auto conductor = [&] {
        auto metal = o.Get("metal"), eta = o.Get("eta"), k = o.Get("k");
        if (metal && (eta || k)) (eta ? *eta : *k).Fail("give either metal or eta and k");
        if (metal) {
            std::vector<std::string> names;
            for (const Metal& mt : kMetals) names.push_back(mt.name);
            const Metal& mt = kMetals[ParseEnum(*metal, names, "metal")];
            m.conductor_eta = mt.eta;
            m.conductor_k = mt.k;
        } else if (eta && k) {
            m.conductor_eta = NonNegativeRgb(*eta);
            m.conductor_k = NonNegativeRgb(*k);
        } else {
            o.Fail("a " + kMaterialTypes[type] + " needs 'metal', or both 'eta' and 'k'");
        }
        if (auto r = o.Get("specular_reflectance")) {
            m.specular_reflectance = ParseReflectance(*r, ctx, true);
        } else {
            m.specular_reflectance.where = v.Where();
            m.specular_reflectance.value = Rgb(1);
        }
    };
    switch (m.kind) {
        case MaterialKind::kDiffuse:
            m.reflectance = reflectance(0.5f);
            break;
        case MaterialKind::kMirror:
            m.reflectance = reflectance(1.0f);
            break;
        case MaterialKind::kDielectric:
            m.eta = ParseEta(o);
            break;
        case MaterialKind::kRoughConductor:
            conductor();
            ParseAlpha(o, &m, 0.1f, false, true);
            ParseDistribution(o, &m);
            break;
        case MaterialKind::kConductor:
            conductor();
            break;
        case MaterialKind::kRoughDielectric:
            m.eta = ParseEta(o);
            ParseAlpha(o, &m, 0.1f, false, false);
            ParseDistribution(o, &m);
            break;
        case MaterialKind::kPlastic:
            m.reflectance = reflectance(0.5f);
            m.eta = ParseEta(o);
            ParseAlpha(o, &m, 0.0f, true, false);
            ParseDistribution(o, &m);
            break;
        case MaterialKind::kBlend: {
            JsonValue parts = o.Required("materials");
            if (!parts.IsArray() || parts.Size() != 2)
                parts.Fail("expected a list of two materials (names or records)");
            std::vector<JsonValue> elements = parts.Elements();
            for (int i = 0; i < 2; ++i)
                m.parts[i] = ParseBlendPart(elements[i], ctx, inline_materials);
            JsonValue w = o.Required("weight");
            m.weight.where = w.Where();
            if (w.IsString()) {
                m.weight.texture = ParseReference(w, ctx.textures, "texture");
            } else {
                if (!w.IsNumber())
                    w.Fail("expected a number in [0, 1] or a texture name, got " + w.KindName());
                m.weight.value = Rgb(InRange(w, 0, 1, false, false));
            }
            break;
        }
        case MaterialKind::kMeasured: {
            JsonValue file = o.Required("file");
            m.path = ctx.ResolveFile(file, "BRDF file");
            m.path_where = file.Where();
            std::string ext = fs::path(m.path).extension().string();
            for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
            if (ext != ".binary" && ext != ".brdf")
                file.Fail(
                    "a measured BRDF is a MERL '.binary' file or an irregularly sampled "
                    "'.brdf' file, got '" +
                    ext + "'");
            // In MeasuredSampling's order.
            if (auto s = o.Get("sampling"))
                m.measured_sampling = MeasuredSampling(
                    ParseEnum(*s, {"factored", "cosine", "fit"}, "measured BRDF sampling"));
            // The factorisation's J (outer terms) and K (inner terms per outer one).
            if (auto t = o.Get("terms")) {
                if (m.measured_sampling != MeasuredSampling::kFactored)
                    t->Fail("'terms' belongs to \"sampling\": \"factored\"");
                if (t->IsArray()) {
                    if (t->Size() != 2) t->Fail("'terms' is [J, K] or one number for both");
                    const std::vector<JsonValue> jk = t->Elements();
                    m.factored_terms = {int(jk[0].AsInt(1, 8)), int(jk[1].AsInt(1, 8))};
                } else {
                    const int n = int(t->AsInt(1, 8));
                    m.factored_terms = {n, n};
                }
            }
            break;
        }
    }
    o.Finish("a " + kMaterialTypes[type] + " material");
    return m;
}

enum class VisitState { kUnvisited, kOpen, kDone };

void VisitBlendParts(const std::vector<MaterialRecord>& materials, int i,
                     std::vector<VisitState>* state) {
    (*state)[i] = VisitState::kOpen;
    const MaterialRecord& m = materials[i];
    if (m.kind == MaterialKind::kBlend) {
        for (int part : m.parts) {
            if ((*state)[part] == VisitState::kOpen) {
                std::string what = m.name.empty() ? "this blend" : "blend '" + m.name + "'";
                throw SceneError(m.where, what + " contains itself through its materials");
            }
            if ((*state)[part] == VisitState::kUnvisited) VisitBlendParts(materials, part, state);
        }
    }
    (*state)[i] = VisitState::kDone;
}

// A blend that contains itself, through any chain of parts, has no meaning: fails at
// the first such blend found.
void CheckBlendCycles(const std::vector<MaterialRecord>& materials) {
    std::vector<VisitState> state(materials.size(), VisitState::kUnvisited);
    for (size_t i = 0; i < materials.size(); ++i)
        if (state[i] == VisitState::kUnvisited) VisitBlendParts(materials, int(i), &state);
}

// ---------------------------------------------------------------------------------------
// shapes, objects, instances

const std::vector<std::string> kShapeTypes = {"sphere", "rectangle", "disk",     "box",
                                              "quad",   "mesh",      "triangles"};

std::optional<EmissionRecord> ParseEmission(const JsonValue& v) {
    JsonObject o = v.AsObject();
    EmissionRecord e;
    e.radiance = NonNegativeRgb(o.Required("radiance"));
    if (auto t = o.Get("two_sided")) e.two_sided = t->AsBool();
    o.Finish("emission");
    if (e.radiance.IsBlack()) return std::nullopt;  // glows with nothing: not a light
    return e;
}

// Inline triangle meshes ("triangles"). Their vertices are numbered by 32-bit indices, as
// those of mesh files; like a mesh file, the data counts towards the size limit of the
// file that holds it (the scene file).
constexpr uint64_t kMaxInlineVertices = uint64_t(UINT32_MAX);

// A list of tuples of `arity` numbers, one per vertex or triangle, written either nested
// ([[x, y, z], ...]) or flat ([x, y, z, ...]); its first element tells which.
class TupleList {
  public:
    TupleList(const JsonValue& v, size_t arity, const std::string& what)
        : value_(v), arity_(arity), elements_(v.Elements()) {
        flat_ = !elements_.empty() && elements_[0].IsNumber();
        if (flat_ && elements_.size() % arity_ != 0)
            v.Fail("a flat list of " + what + "s needs " + std::to_string(arity_) +
                   " numbers per " + what + ", got " + std::to_string(elements_.size()) +
                   " numbers");
        if (Size() > kMaxInlineVertices)
            v.Fail("too many " + what + "s (" + std::to_string(Size()) + "; at most " +
                   std::to_string(kMaxInlineVertices) + ")");
        for (size_t i = 0; !flat_ && i < elements_.size(); ++i) {
            const JsonValue& e = elements_[i];
            if (!e.IsArray() || e.Size() != arity_)
                e.Fail("expected a " + what + " of " + std::to_string(arity_) + " numbers, got " +
                       (e.IsArray() ? "an array of " + std::to_string(e.Size()) : e.KindName()));
        }
    }
    const JsonValue& Value() const { return value_; }
    size_t Size() const { return flat_ ? elements_.size() / arity_ : elements_.size(); }
    // Where tuple i is written: its own array, or (flat) its first number.
    const JsonValue& Where(size_t i) const { return elements_[flat_ ? i * arity_ : i]; }
    // The numbers of tuple i, each still able to name its place.
    std::vector<JsonValue> Numbers(size_t i) const {
        if (!flat_) return elements_[i].Elements();
        return {elements_.begin() + std::ptrdiff_t(i * arity_),
                elements_.begin() + std::ptrdiff_t((i + 1) * arity_)};
    }
    std::vector<float> Floats(size_t i) const {
        std::vector<float> out;
        for (const JsonValue& n : Numbers(i)) out.push_back(n.AsFloat());
        return out;
    }

  private:
    JsonValue value_;
    size_t arity_;
    std::vector<JsonValue> elements_;
    bool flat_ = false;
};

// A per-vertex attribute list: as many tuples as there are positions.
TupleList VertexAttribute(const JsonValue& v, size_t arity, const std::string& what,
                          size_t num_positions) {
    TupleList list(v, arity, what);
    if (list.Size() != num_positions)
        v.Fail(std::to_string(list.Size()) + " " + what + "s for " + std::to_string(num_positions) +
               " positions: give one per vertex, or none");
    return list;
}

// The mesh of a "triangles" shape, checked value by value so that each mistake is named
// at its place in the file.
TriangleMesh ParseInlineMesh(JsonObject& o) {
    TriangleMesh m;
    TupleList positions(o.Required("positions"), 3, "position");
    if (positions.Size() == 0) positions.Value().Fail("an inline mesh needs vertices");
    for (size_t i = 0; i < positions.Size(); ++i) {
        std::vector<float> p = positions.Floats(i);
        m.positions.push_back({p[0], p[1], p[2]});
    }
    const size_t num_vertices = m.positions.size();

    TupleList indices(o.Required("indices"), 3, "triangle");
    if (indices.Size() == 0) indices.Value().Fail("an inline mesh needs at least one triangle");
    for (size_t t = 0; t < indices.Size(); ++t) {
        uint32_t corner[3];
        std::vector<JsonValue> numbers = indices.Numbers(t);
        for (int k = 0; k < 3; ++k) {
            const JsonValue& n = numbers[size_t(k)];
            double d = n.AsDouble();
            if (d != std::floor(d)) n.Fail("a vertex index must be an integer, got " + Number(d));
            if (d < 0 || d >= double(num_vertices))
                n.Fail("vertex index " + Number(d) + " is out of range: the mesh has " +
                       std::to_string(num_vertices) + " vertices (0 to " +
                       std::to_string(num_vertices - 1) + ")");
            corner[k] = uint32_t(d);
        }
        const JsonValue& where = indices.Where(t);
        if (corner[0] == corner[1] || corner[1] == corner[2] || corner[0] == corner[2])
            where.Fail("triangle " + std::to_string(t) +
                       " is degenerate: it uses one vertex twice");
        const Vec3 &a = m.positions[corner[0]], &b = m.positions[corner[1]],
                   &c = m.positions[corner[2]];
        if (LengthSquared(Cross(b - a, c - a)) == 0)
            where.Fail("triangle " + std::to_string(t) +
                       " is degenerate: its corners are collinear (zero area)");
        m.indices.insert(m.indices.end(), {corner[0], corner[1], corner[2]});
    }

    if (auto nv = o.Get("normals")) {
        TupleList normals = VertexAttribute(*nv, 3, "normal", num_vertices);
        for (size_t i = 0; i < normals.Size(); ++i) {
            std::vector<float> n = normals.Floats(i);
            Vec3 normal(n[0], n[1], n[2]);
            if (LengthSquared(normal) == 0) normals.Where(i).Fail("a normal must not be zero");
            m.normals.push_back(normal);
        }
    }
    if (auto uv = o.Get("uvs")) {
        TupleList uvs = VertexAttribute(*uv, 2, "uv", num_vertices);
        for (size_t i = 0; i < uvs.Size(); ++i) {
            std::vector<float> t = uvs.Floats(i);
            m.uvs.push_back({t[0], t[1]});
        }
    }
    return m;
}

// `in_object`: a shape of an instanced object, which can neither emit nor be a sphere
// (prototypes hold meshes only).
ShapeRecord ParseShape(const JsonValue& v, const Context& ctx, bool in_object) {
    JsonObject o = v.AsObject();
    ShapeRecord s;
    s.where = v.Where();
    JsonValue type_v = o.Required("type");
    int type = ParseEnum(type_v, kShapeTypes, "shape type");
    if (auto n = o.Get("name")) s.name = n->AsString();
    s.kind = ShapeKind(type);
    if (in_object && s.kind == ShapeKind::kSphere)
        type_v.Fail("spheres cannot be part of an instanced object (objects hold meshes only)");

    switch (s.kind) {
        case ShapeKind::kSphere:
            if (auto c = o.Get("center")) s.center = c->AsVec3();
            if (auto r = o.Get("radius")) s.radius = Positive(*r);
            if (o.Has("transform"))
                o.Required("transform")
                    .Fail("a sphere takes 'center' and 'radius', not a transform");
            break;
        case ShapeKind::kRectangle:
            if (auto w = o.Get("width")) s.width = Positive(*w);
            if (auto h = o.Get("height")) s.height = Positive(*h);
            break;
        case ShapeKind::kDisk:
            if (auto r = o.Get("radius")) s.radius = Positive(*r);
            if (auto n = o.Get("segments")) s.segments = int(n->AsInt(3, 1 << 20));
            break;
        case ShapeKind::kBox: {
            if (auto lo = o.Get("min")) s.lo = lo->AsVec3();
            auto hi = o.Get("max");
            if (hi) s.hi = hi->AsVec3();
            if (!(s.lo.x < s.hi.x && s.lo.y < s.hi.y && s.lo.z < s.hi.z))
                (hi ? *hi : v).Fail("box max must exceed min on every axis");
            break;
        }
        case ShapeKind::kQuad: {
            JsonValue verts = o.Required("vertices");
            if (!verts.IsArray() || verts.Size() != 4)
                verts.Fail("expected an array of 4 points, got " +
                           (verts.IsArray() ? std::to_string(verts.Size()) + " points"
                                            : verts.KindName()));
            std::vector<JsonValue> pts = verts.Elements();
            for (int i = 0; i < 4; ++i) s.corners[i] = pts[i].AsVec3();
            const auto& c = s.corners;
            Vec3 n = Cross(c[1] - c[0], c[2] - c[0]) + Cross(c[2] - c[0], c[3] - c[0]);
            if (LengthSquared(n) == 0) verts.Fail("quad is degenerate (zero area)");
            break;
        }
        case ShapeKind::kMesh: {
            auto resolve_mesh = [&](const JsonValue& file) {
                std::string path = ctx.ResolveFile(file, "mesh file");
                std::string ext = fs::path(path).extension().string();
                for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
                if (ext != ".obj" && ext != ".ply")
                    file.Fail("unsupported mesh format '" + ext + "' (expected .obj or .ply)");
                return path;
            };
            if (auto deform = o.Get("deform")) {
                if (o.Has("file"))
                    o.Required("file").Fail(
                        "a deforming mesh names its files in 'deform', not in 'file'");
                if (in_object) deform->Fail("shapes of instanced objects cannot deform");
                if (o.Has("emission")) deform->Fail("emitting shapes cannot deform");
                JsonObject d = deform->AsObject();
                s.deform_interpolation = ParseInterpolationKey(d);
                std::vector<JsonValue> elements = AnimationKeys(d, "a deformation");
                std::vector<double> times;
                for (const JsonValue& kv : elements) {
                    JsonObject k = kv.AsObject();
                    DeformKey key;
                    key.time = ParseKeyTime(k, kv, ctx.fps);
                    JsonValue file = k.Required("file");
                    key.path = resolve_mesh(file);
                    key.where = file.Where();
                    k.Finish("a deformation key");
                    times.push_back(key.time);
                    s.deform.push_back(key);
                }
                CheckKeyOrder(times, elements);
                s.path = s.deform[0].path;
                s.path_where = s.deform[0].where;
                break;
            }
            JsonValue file = o.Required("file");
            s.path = resolve_mesh(file);
            s.path_where = file.Where();
            break;
        }
        case ShapeKind::kTriangles:
            s.triangles = ParseInlineMesh(o);
            break;
    }
    if (s.kind != ShapeKind::kSphere) {
        if (auto t = o.Get("transform")) s.transform = ParseTransform(*t);
    }
    if (auto a = o.Get("animation")) {
        if (in_object)
            a->Fail("shapes of instanced objects cannot be animated; animate the instance");
        if (o.Has("emission"))
            a->Fail("emitting shapes cannot be animated (lights stay where they are)");
        s.animation = ParseAnimation(*a, ctx.fps);
    }

    if (in_object && o.Has("emission"))
        o.Required("emission").Fail("shapes of instanced objects cannot emit light");
    std::optional<JsonValue> emission = in_object ? std::nullopt : o.Get("emission");
    if (emission) s.emission = ParseEmission(*emission);
    // An emitter may have no material: it then only glows and reflects nothing.
    std::optional<JsonValue> material = emission ? o.Get("material") : o.Required("material");
    if (material) s.material = ParseReference(*material, ctx.materials, "material");
    o.Finish(s.kind == ShapeKind::kTriangles ? "a triangles shape" : "a " + kShapeTypes[type]);
    return s;
}

std::vector<ShapeRecord> ParseShapeList(const JsonValue& v, const Context& ctx, bool in_object) {
    std::vector<ShapeRecord> out;
    for (const JsonValue& s : v.Elements()) out.push_back(ParseShape(s, ctx, in_object));
    return out;
}

ObjectRecord ParseObject(const std::string& name, const JsonValue& v, const Context& ctx) {
    JsonObject o = v.AsObject();
    ObjectRecord r;
    r.name = name;
    r.where = v.Where();
    JsonValue shapes = o.Required("shapes");
    r.shapes = ParseShapeList(shapes, ctx, true);
    if (r.shapes.empty()) shapes.Fail("an object needs at least one shape");
    o.Finish("an object");
    return r;
}

InstanceRecord ParseInstance(const JsonValue& v, const Context& ctx) {
    JsonObject o = v.AsObject();
    InstanceRecord r;
    r.where = v.Where();
    r.object = ParseReference(o.Required("object"), ctx.objects, "object");
    if (auto t = o.Get("transform")) r.transform = ParseTransform(*t);
    if (auto a = o.Get("animation")) r.animation = ParseAnimation(*a, ctx.fps);
    o.Finish("an instance");
    return r;
}

// ---------------------------------------------------------------------------------------
// lights

const std::vector<std::string> kLightTypes = {"point", "spot", "directional", "environment"};

LightRecord ParseLight(const JsonValue& v, const Context& ctx) {
    JsonObject o = v.AsObject();
    LightRecord l;
    l.where = v.Where();
    int type = ParseEnum(o.Required("type"), kLightTypes, "light type");
    l.kind = LightKind(type);
    switch (l.kind) {
        case LightKind::kPoint:
            l.position = o.Required("position").AsVec3();
            l.value = NonNegativeRgb(o.Required("intensity"));
            break;
        case LightKind::kSpot: {
            l.position = o.Required("position").AsVec3();
            JsonValue target = o.Required("target");
            l.target = target.AsVec3();
            if (l.target == l.position) target.Fail("target must differ from position");
            l.value = NonNegativeRgb(o.Required("intensity"));
            if (auto c = o.Get("cone_angle")) l.cone_angle = InRange(*c, 0, 180, true, false);
            l.falloff_start = std::max(0.0f, l.cone_angle - 5);
            if (auto f = o.Get("falloff_start")) {
                l.falloff_start = NonNegative(*f);
                if (l.falloff_start > l.cone_angle)
                    f->Fail("falloff_start must not exceed cone_angle (" + Number(l.cone_angle) +
                            ")");
            }
            break;
        }
        case LightKind::kDirectional:
            l.direction = Normalize(NonZeroVec3(o.Required("direction")));
            l.value = NonNegativeRgb(o.Required("irradiance"));
            break;
        case LightKind::kEnvironment: {
            auto file = o.Get("file");
            if (file && o.Has("radiance"))
                file->Fail("an environment light has either 'radiance' or 'file', not both");
            if (file) {
                l.path = ctx.ResolveFile(*file, "environment map");
                l.path_where = file->Where();
            } else {
                l.value = NonNegativeRgb(o.Required("radiance"));
            }
            if (auto s = o.Get("scale")) l.scale = NonNegativeRgb(*s);
            if (auto s = o.Get("sampling")) {
                if (!file) s->Fail("only an environment map has a sampling choice");
                l.sampling = EnvironmentSampling(ParseEnum(
                    *s,
                    {std::begin(kEnvironmentSamplingNames), std::end(kEnvironmentSamplingNames)},
                    "environment sampling"));
            }
            if (auto n = o.Get("strata")) {
                if (l.sampling != EnvironmentSampling::kStructured &&
                    l.sampling != EnvironmentSampling::kLightSet)
                    n->Fail("'strata' belongs to \"sampling\": \"structured\" or \"lightset\"");
                l.strata = int(n->AsInt(1, 1 << 20));
            }
            if (auto r = o.Get("rotate")) {
                JsonObject ro = r->AsObject();
                const Vec3 axis = NonZeroVec3(ro.Required("axis"));
                const float angle = ro.Required("angle").AsFloat();
                ro.Finish("rotate");
                l.rotation = Transform::Rotate(angle, axis);
            }
            if (auto m = o.Get("mirror")) {
                if (!file) m->Fail("only an environment map can be mirrored");
                // u -> 1 - u in the map's frame, before the rotation.
                if (m->AsBool()) l.rotation = l.rotation * Transform::Scale({1, 1, -1});
            }
            break;
        }
    }
    o.Finish("a " + kLightTypes[type] + " light");
    return l;
}

// ---------------------------------------------------------------------------------------
// the document

// `ctx` holds where files are looked up; `shown` names the scene file in messages.
SceneRecords ParseDocument(const JsonDocument& doc, const std::string& shown, Context ctx) {
    JsonValue root_v = doc.Root();
    JsonObject root = root_v.AsObject();
    SceneRecords rec;
    rec.file = shown;
    rec.sandbox_root = ctx.sandbox_root.string();

    auto render = root.Get("render"), animation = root.Get("animation");
    JsonValue camera = root.Required("camera");
    auto textures = root.Get("textures"), materials = root.Get("materials");
    auto shapes = root.Get("shapes"), objects = root.Get("objects");
    auto instances = root.Get("instances"), lights = root.Get("lights");
    // Unknown top-level keys first: a misspelt section would otherwise pass as empty.
    root.Finish("a scene");

    if (render) rec.render = ParseRender(*render);
    if (animation) rec.animation = ParseAnimationSettings(*animation);
    ctx.fps = rec.animation.fps;
    rec.camera = ParseCamera(camera, ctx.fps);
    if (textures) {
        ctx.section = "textures";
        for (auto& [name, value] : textures->AsObject().Entries()) {
            ctx.textures[name] = int(rec.textures.size());
            rec.textures.push_back(ParseTexture(name, value, ctx));
        }
    }
    if (materials) {
        ctx.section = "materials";
        // Every name first, so that a blend may refer to a material defined after it.
        auto entries = materials->AsObject().Entries();
        int next = 0;
        for (auto& [name, value] : entries) ctx.materials[name] = next++;
        InlineMaterials inline_materials;
        inline_materials.first = int(entries.size());
        for (auto& [name, value] : entries)
            rec.materials.push_back(ParseMaterial(name, value, ctx, &inline_materials));
        for (MaterialRecord& m : inline_materials.records) rec.materials.push_back(std::move(m));
        CheckBlendCycles(rec.materials);
    }
    ctx.section = "shapes";
    if (shapes) rec.shapes = ParseShapeList(*shapes, ctx, false);
    if (objects) {
        ctx.section = "objects";
        for (auto& [name, value] : objects->AsObject().Entries()) {
            ctx.objects[name] = int(rec.objects.size());
            rec.objects.push_back(ParseObject(name, value, ctx));
        }
    }
    if (instances) {
        for (const JsonValue& i : instances->Elements())
            rec.instances.push_back(ParseInstance(i, ctx));
    }
    if (lights) {
        ctx.section = "lights";
        for (const JsonValue& l : lights->Elements()) rec.lights.push_back(ParseLight(l, ctx));
    }

    // Sections were parsed in dependency order; list their files in the file's order.
    std::vector<std::string> seen;
    for (const std::string& section : root.Keys()) {
        for (const Context::FileRef& f : ctx.files) {
            if (f.section != section) continue;
            if (std::find(seen.begin(), seen.end(), f.resolved) != seen.end()) continue;
            seen.push_back(f.resolved);
            rec.referenced_files.push_back(f.written);
        }
    }
    return rec;
}

// A pbrt scene: converted in memory (scene/pbrt_import.h), then parsed like any scene; the
// files it includes are read under the same rules as the files it references, and listed
// first among them. Errors in the converted scene name the pbrt file and line.
SceneRecords ParsePbrtDocument(const std::string& text, const std::string& shown, Context ctx) {
    const PbrtImport pbrt = ImportPbrt(
        shown, text, [&ctx](const std::string& given) { return ctx.ReadIncluded(given); });
    LogPbrtWarnings(pbrt);
    SceneRecords rec;
    try {
        rec = ParseDocument(JsonDocument::Parse(pbrt.json, shown), shown, std::move(ctx));
    } catch (const SceneError& e) {
        throw pbrt.Relocate(e);
    }
    std::vector<std::string> files = pbrt.included_files;
    for (std::string& f : rec.referenced_files)
        if (std::find(files.begin(), files.end(), f) == files.end()) files.push_back(std::move(f));
    rec.referenced_files = std::move(files);
    return rec;
}

// The scene file's text, in Tessera's format or (by its extension) pbrt's.
SceneRecords ParseSceneDocument(const std::string& text, const std::string& shown, Context ctx) {
    if (IsPbrtFile(shown)) return ParsePbrtDocument(text, shown, std::move(ctx));
    return ParseDocument(JsonDocument::Parse(text, shown), shown, std::move(ctx));
}

// A scene from a bundle: the scene file itself passes the same checks as its references,
// and is named relative to the bundle root.
SceneRecords ParseSandboxedSceneFile(const std::string& path, const SceneLoadOptions& options) {
    const fs::path scene = fs::absolute(path).lexically_normal();
    fs::path root = options.sandbox_root.empty()
                        ? scene.parent_path()
                        : fs::absolute(options.sandbox_root).lexically_normal();
    if (!root.has_filename()) root = root.parent_path();  // a trailing '/'
    const fs::path rel = scene.lexically_relative(root);
    const std::string shown = rel.generic_string();
    if (rel.empty() || !StaysInBundle(shown))
        throw std::invalid_argument("the scene file is not inside its sandbox root");
    if (std::string why = CheckBundleFile(root, rel, options.max_file_bytes); !why.empty())
        throw SceneError(shown, "scene file " + why);
    std::string text;
    try {
        text = ReadFileBelow(root.string(), rel.string(), options.max_file_bytes);
    } catch (const std::runtime_error& e) {
        throw SceneError(shown, std::string("scene file ") + e.what());
    }
    Context ctx;
    ctx.base_dir = scene.parent_path();
    ctx.sandbox_root = root;
    ctx.scene_dir_in_bundle = rel.parent_path();
    ctx.max_file_bytes = options.max_file_bytes;
    return ParseSceneDocument(text, shown, std::move(ctx));
}

Context LocalContext(const std::string& path, uint64_t max_file_bytes) {
    Context ctx;
    ctx.base_dir = fs::path(path).parent_path();
    ctx.max_file_bytes = max_file_bytes;
    return ctx;
}

}  // namespace

namespace {

// A scene file outside any sandbox, read under the same size limit as the files it names
// (its inline meshes count towards it).
std::string ReadLocalSceneFile(const std::string& path, uint64_t max_file_bytes) {
    try {
        return ReadFileBytes(path, max_file_bytes, path);
    } catch (const std::runtime_error& e) {
        throw SceneError(path, std::string("scene file ") + e.what());
    }
}

}  // namespace

SceneRecords ParseSceneFile(const std::string& path, const SceneLoadOptions& options) {
    SceneRecords rec = options.sandboxed
                           ? ParseSandboxedSceneFile(path, options)
                           : ParseSceneDocument(ReadLocalSceneFile(path, options.max_file_bytes),
                                                path, LocalContext(path, options.max_file_bytes));
    rec.max_file_bytes = options.max_file_bytes;
    rec.image_limits = options.image_limits;
    return rec;
}

SceneRecords ParseSceneText(const std::string& text, const std::string& path) {
    return ParseSceneDocument(text, path, LocalContext(path, SceneLoadOptions().max_file_bytes));
}

}  // namespace tessera

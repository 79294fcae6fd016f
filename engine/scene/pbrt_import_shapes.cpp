// The pbrt converter's shapes and object instancing (scene/pbrt_converter.h): triangle and
// bilinear meshes, PLY files, spheres and disks, and objects with their instances.

#include <algorithm>
#include <cmath>

#include "scene/pbrt_converter.h"

namespace tessera::pbrt {
namespace {

std::string EmissionJson(const AreaLight& a) {
    JsonMembers e;
    e.Add("radiance", JsonRgb(a.radiance));
    if (a.two_sided) e.Add("two_sided", "true");
    return e.Str();
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Shapes

std::optional<Converter::Mesh> Converter::ReadMesh(ParamSet& ps, const Loc& loc,
                                                   const std::string& desc, bool bilinear) {
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
        Warn(loc, desc + ": \"indices\" must list " + std::to_string(corners) + " vertices per " +
                      (bilinear ? "patch" : "triangle") + "; skipped");
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
            const Vec3 v{float((*n)[3 * i]), float((*n)[3 * i + 1]), float((*n)[3 * i + 2])};
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

std::string Converter::MeshJson(const Mesh& m) {
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

std::string Converter::ShapeMaterial() {
    return state_.material.empty() ? DefaultMaterial() : state_.material;
}

void Converter::Shape(const Loc& loc, const std::string& type, ParamSet& ps,
                      const std::string& desc) {
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

void Converter::AddShape(const std::string& json, const Loc& loc) {
    if (current_object_) {
        current_object_->shapes.push_back(json);
        current_object_->shape_locs.push_back(loc);
        return;
    }
    origins_.emplace_back("/shapes/" + std::to_string(shapes_.size()), loc.Str());
    shapes_.push_back(json);
}

void Converter::Sphere(const Loc& loc, ParamSet& ps, const std::string& desc,
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
void Converter::EmitSphere(const SphereDef& s, const M4& instance,
                           const std::optional<AreaLight>& emit) {
    const M4 xf = world_ * instance * s.ctm;
    const double l0 = Length(xf.Column(0)), l1 = Length(xf.Column(1)), l2 = Length(xf.Column(2));
    const double lo = std::min({l0, l1, l2}), hi = std::max({l0, l1, l2});
    const V3 c0 = xf.Column(0), c1 = xf.Column(1), c2 = xf.Column(2);
    const double shear =
        std::max({std::abs(Dot(c0, c1)), std::abs(Dot(c1, c2)), std::abs(Dot(c0, c2))}) / (hi * hi);
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

// ---------------------------------------------------------------------------------------
// Instancing

void Converter::ObjectBegin(const Token& d, const std::string& name) {
    stack_.push_back({state_, false, d.loc});
    if (current_object_) Warn(d.loc, "ObjectBegin inside an object definition; the outer one ends");
    auto def = std::make_shared<ObjectDef>();
    def->json_name = UniqueName(object_names_, name);
    if (objects_.count(name)) Warn(d.loc, "ObjectBegin: \"" + name + "\" is defined again");
    objects_[name] = def;
    current_object_ = def;
    current_object_loc_ = d.loc;
}

void Converter::ObjectEnd(const Token& d) {
    if (!current_object_) return Warn(d.loc, "ObjectEnd without ObjectBegin; ignored");
    ObjectDef& def = *current_object_;
    if (!def.shapes.empty()) {
        const std::string ptr = "/objects/" + PointerKey(def.json_name);
        origins_.emplace_back(ptr, current_object_loc_.Str());
        for (size_t i = 0; i < def.shape_locs.size(); ++i)
            origins_.emplace_back(ptr + "/shapes/" + std::to_string(i), def.shape_locs[i].Str());
        std::string s;
        for (size_t i = 0; i < def.shapes.size(); ++i) s += (i ? ",\n    " : "") + def.shapes[i];
        object_json_.emplace_back(def.json_name, "{\"shapes\": [\n    " + s + "]}");
    }
    current_object_.reset();
    if (!stack_.empty()) {
        state_ = stack_.back().state;
        stack_.pop_back();
    }
}

void Converter::ObjectInstance(const Token& d, const std::string& name) {
    if (current_object_) return Warn(d.loc, "ObjectInstance inside an object definition; skipped");
    auto it = objects_.find(name);
    if (it == objects_.end()) return Warn(d.loc, "ObjectInstance: unknown object '" + name + "'");
    const ObjectDef& def = *it->second;
    DecideMirror();
    // The object's shapes carry world_ * (their transform); the instance conjugates
    // pbrt's by the mirror (world_ is its own inverse), which composes to
    // world_ * instance * shape.
    if (!def.shapes.empty()) {
        const M4 xf = world_ * state_.ctm * world_;
        if (!xf.IsAffine() || !(std::abs(xf.Det3()) > 1e-30))
            return Warn(d.loc, "ObjectInstance: its transform is singular or projective; skipped");
        JsonMembers j;
        j.Add("object", Quote(def.json_name));
        if (!xf.IsIdentity()) j.Add("transform", JsonMatrix(xf));
        origins_.emplace_back("/instances/" + std::to_string(instances_.size()), d.loc.Str());
        instances_.push_back(j.Str());
    }
    for (const SphereDef& s : def.spheres) EmitSphere(s, state_.ctm, std::nullopt);
}

}  // namespace tessera::pbrt

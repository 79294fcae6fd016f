#include "scene/mesh.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <tuple>
#include <unordered_map>

namespace tessera {

namespace {

bool IsFinite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Determinant of the upper-left 3x3 block: negative when the transform mirrors.
double LinearDeterminant(const Mat4& m) {
    const auto& a = m.m;
    return double(a[0][0]) * (double(a[1][1]) * a[2][2] - double(a[1][2]) * a[2][1]) -
           double(a[0][1]) * (double(a[1][0]) * a[2][2] - double(a[1][2]) * a[2][0]) +
           double(a[0][2]) * (double(a[1][0]) * a[2][1] - double(a[1][1]) * a[2][0]);
}

}  // namespace

void TriangleMesh::Transform(const tessera::Transform& xf) {
    for (Vec3& p : positions) p = xf.Point(p);
    for (Vec3& n : normals) {
        Vec3 t = xf.Normal(n);
        float len = Length(t);
        n = len > 0 ? t / len : t;
    }
    // A mirroring transform turns counter-clockwise triangles clockwise; swapping two
    // corners keeps each triangle's front (right-hand rule) on the same side as before.
    if (LinearDeterminant(xf.Matrix()) < 0) {
        for (size_t i = 0; i + 2 < indices.size(); i += 3)
            std::swap(indices[i + 1], indices[i + 2]);
    }
}

void TriangleMesh::Validate() const {
    if (indices.size() % 3 != 0) {
        throw std::runtime_error("index count " + std::to_string(indices.size()) +
                                 " is not a multiple of 3");
    }
    if (!normals.empty() && normals.size() != positions.size()) {
        throw std::runtime_error(std::to_string(normals.size()) + " normals for " +
                                 std::to_string(positions.size()) + " positions");
    }
    if (!uvs.empty() && uvs.size() != positions.size()) {
        throw std::runtime_error(std::to_string(uvs.size()) + " uvs for " +
                                 std::to_string(positions.size()) + " positions");
    }
    for (size_t i = 0; i < indices.size(); ++i) {
        if (indices[i] >= positions.size()) {
            throw std::runtime_error("triangle " + std::to_string(i / 3) + " uses vertex " +
                                     std::to_string(indices[i]) + " but there are only " +
                                     std::to_string(positions.size()) + " vertices");
        }
    }
    for (size_t i = 0; i < positions.size(); ++i) {
        if (!IsFinite(positions[i]))
            throw std::runtime_error("position " + std::to_string(i) + " is not finite");
    }
    for (size_t i = 0; i < normals.size(); ++i) {
        if (!IsFinite(normals[i]))
            throw std::runtime_error("normal " + std::to_string(i) + " is not finite");
    }
    for (size_t i = 0; i < uvs.size(); ++i) {
        if (!std::isfinite(uvs[i].x) || !std::isfinite(uvs[i].y))
            throw std::runtime_error("uv " + std::to_string(i) + " is not finite");
    }
}

TriangleMesh MakeRectangle(float width, float height) {
    float hx = width / 2, hy = height / 2;
    TriangleMesh m;
    m.positions = {{-hx, -hy, 0}, {hx, -hy, 0}, {hx, hy, 0}, {-hx, hy, 0}};
    m.normals.assign(4, Vec3(0, 0, 1));
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

TriangleMesh MakeDisk(float radius, int segments) {
    if (segments < 3) throw std::invalid_argument("a disk needs at least 3 segments");
    TriangleMesh m;
    m.positions.push_back({0, 0, 0});
    m.uvs.push_back({0.5f, 0.5f});
    for (int i = 0; i < segments; ++i) {
        float phi = 2 * kPi * float(i) / float(segments);
        float c = std::cos(phi), s = std::sin(phi);
        m.positions.push_back({radius * c, radius * s, 0});
        // Planar mapping of the disk onto the unit square.
        m.uvs.push_back({0.5f + 0.5f * c, 0.5f + 0.5f * s});
    }
    m.normals.assign(m.positions.size(), Vec3(0, 0, 1));
    for (int i = 0; i < segments; ++i) {
        uint32_t a = 1 + uint32_t(i), b = 1 + uint32_t((i + 1) % segments);
        m.indices.insert(m.indices.end(), {0u, a, b});
    }
    return m;
}

TriangleMesh MakeBox(const Vec3& lo, const Vec3& hi) {
    TriangleMesh m;
    // Each face: outward normal axis and sign; corners listed counter-clockwise as seen
    // from outside, so the right-hand rule gives the outward normal.
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            if (side == 0) std::swap(u, v);  // keeps (u, v, normal) right-handed
            Vec3 n;
            n[axis] = side == 1 ? 1.0f : -1.0f;
            auto corner = [&](int cu, int cv) {
                Vec3 p;
                p[axis] = side == 1 ? hi[axis] : lo[axis];
                p[u] = cu ? hi[u] : lo[u];
                p[v] = cv ? hi[v] : lo[v];
                return p;
            };
            uint32_t base = uint32_t(m.positions.size());
            m.positions.insert(m.positions.end(),
                               {corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)});
            m.uvs.insert(m.uvs.end(), {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
            m.normals.insert(m.normals.end(), 4, n);
            m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
        }
    }
    return m;
}

TriangleMesh MakeQuad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    TriangleMesh m;
    m.positions = {a, b, c, d};
    // No vertex normals: a quad need not be planar, and interpolated normals across its
    // diagonal would bend the shading of a surface that is flat in each triangle.
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

// ---------------------------------------------------------------------------------------
// OBJ

namespace {

TriangleMesh LoadObj(const std::string& path, const std::string& data) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = true;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    // From the text already read; material libraries are not needed (materials come from
    // the scene file), so none is passed.
    if (!reader.ParseFromString(data, "", config)) {
        std::string err = reader.Error();
        while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
        throw std::runtime_error(path +
                                 ": cannot parse OBJ: " + (err.empty() ? "unknown error" : err));
    }
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    size_t num_v = attrib.vertices.size() / 3, num_n = attrib.normals.size() / 3,
           num_t = attrib.texcoords.size() / 2;

    // Normals and uvs are kept only if every face corner has one; OBJ indexes them apart
    // from positions, so each distinct (position, normal, uv) triple becomes one vertex.
    bool all_normals = true, all_uvs = true;
    size_t corners = 0;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
            if (shape.mesh.num_face_vertices[f] != 3)
                throw std::runtime_error(path + ": OBJ face could not be triangulated");
        }
        for (const tinyobj::index_t& idx : shape.mesh.indices) {
            all_normals = all_normals && idx.normal_index >= 0;
            all_uvs = all_uvs && idx.texcoord_index >= 0;
            ++corners;
        }
    }
    if (corners == 0) throw std::runtime_error(path + ": OBJ file has no faces");

    TriangleMesh m;
    std::map<std::tuple<int, int, int>, uint32_t> vertex_of;
    m.indices.reserve(corners);
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        for (size_t k = 0; k < shape.mesh.indices.size(); ++k) {
            const tinyobj::index_t& idx = shape.mesh.indices[k];
            int vn = all_normals ? idx.normal_index : -1;
            int vt = all_uvs ? idx.texcoord_index : -1;
            if (idx.vertex_index < 0 || size_t(idx.vertex_index) >= num_v ||
                (vn >= 0 && size_t(vn) >= num_n) || (vt >= 0 && size_t(vt) >= num_t)) {
                throw std::runtime_error(path + ": OBJ face " + std::to_string(k / 3) + " in '" +
                                         shape.name + "' has an index out of range");
            }
            auto key = std::make_tuple(idx.vertex_index, vn, vt);
            auto [it, inserted] = vertex_of.emplace(key, uint32_t(m.positions.size()));
            if (inserted) {
                const float* p = &attrib.vertices[3 * size_t(idx.vertex_index)];
                m.positions.push_back({p[0], p[1], p[2]});
                if (vn >= 0) {
                    const float* n = &attrib.normals[3 * size_t(vn)];
                    m.normals.push_back({n[0], n[1], n[2]});
                }
                if (vt >= 0) {
                    const float* t = &attrib.texcoords[2 * size_t(vt)];
                    m.uvs.push_back({t[0], t[1]});
                }
            }
            m.indices.push_back(it->second);
        }
    }
    return m;
}

// ---------------------------------------------------------------------------------------
// PLY: ascii, binary_little_endian and binary_big_endian; vertex positions, optional
// normals and uvs; faces as lists of vertex indices, triangulated as fans.

enum class PlyFormat { kAscii, kBinaryLittle, kBinaryBig };

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::kFloat32;
    bool is_list = false;
    PlyType count_type = PlyType::kUint8;
};

struct PlyElement {
    std::string name;
    size_t count = 0;
    std::vector<PlyProperty> properties;
};

std::optional<PlyType> ParsePlyType(std::string_view s) {
    static const std::pair<std::string_view, PlyType> kTypes[] = {
        {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},
        {"uchar", PlyType::kUint8},    {"uint8", PlyType::kUint8},
        {"short", PlyType::kInt16},    {"int16", PlyType::kInt16},
        {"ushort", PlyType::kUint16},  {"uint16", PlyType::kUint16},
        {"int", PlyType::kInt32},      {"int32", PlyType::kInt32},
        {"uint", PlyType::kUint32},    {"uint32", PlyType::kUint32},
        {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32},
        {"double", PlyType::kFloat64}, {"float64", PlyType::kFloat64}};
    for (const auto& [name, type] : kTypes)
        if (name == s) return type;
    return std::nullopt;
}

size_t PlyTypeSize(PlyType t) {
    switch (t) {
        case PlyType::kInt8:
        case PlyType::kUint8:
            return 1;
        case PlyType::kInt16:
        case PlyType::kUint16:
            return 2;
        case PlyType::kInt32:
        case PlyType::kUint32:
        case PlyType::kFloat32:
            return 4;
        case PlyType::kFloat64:
            return 8;
    }
    return 0;
}

// Reads the body of a PLY file value by value, in whichever encoding the header named.
// Read() returns false at a malformed value or the end of the data; Error() says which.
class PlyBodyReader {
  public:
    PlyBodyReader(const std::string& data, size_t pos, PlyFormat format)
        : data_(data), pos_(pos), format_(format) {}

    bool Read(PlyType type, double* value) {
        return format_ == PlyFormat::kAscii ? ReadAscii(type, value) : ReadBinary(type, value);
    }
    const std::string& Error() const { return error_; }

  private:
    bool ReadAscii(PlyType type, double* value) {
        while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
        size_t start = pos_;
        while (pos_ < data_.size() && !std::isspace(static_cast<unsigned char>(data_[pos_])))
            ++pos_;
        if (start == pos_) return Fail("unexpected end of file");
        const char* first = data_.data() + start;
        const char* last = data_.data() + pos_;
        auto res = std::from_chars(first, last, *value);
        if (res.ec != std::errc() || res.ptr != last)
            return Fail("'" + std::string(first, last) + "' is not a number");
        if (type != PlyType::kFloat32 && type != PlyType::kFloat64 && *value != std::floor(*value))
            return Fail("'" + std::string(first, last) + "' is not an integer");
        return true;
    }

    bool ReadBinary(PlyType type, double* value) {
        size_t size = PlyTypeSize(type);
        if (pos_ + size > data_.size()) return Fail("unexpected end of file");
        unsigned char bytes[8];
        std::memcpy(bytes, data_.data() + pos_, size);
        pos_ += size;
        bool file_little = format_ == PlyFormat::kBinaryLittle;
        if (file_little != (std::endian::native == std::endian::little))
            std::reverse(bytes, bytes + size);
        switch (type) {
            case PlyType::kInt8:
                *value = Load<int8_t>(bytes);
                break;
            case PlyType::kUint8:
                *value = Load<uint8_t>(bytes);
                break;
            case PlyType::kInt16:
                *value = Load<int16_t>(bytes);
                break;
            case PlyType::kUint16:
                *value = Load<uint16_t>(bytes);
                break;
            case PlyType::kInt32:
                *value = Load<int32_t>(bytes);
                break;
            case PlyType::kUint32:
                *value = Load<uint32_t>(bytes);
                break;
            case PlyType::kFloat32:
                *value = Load<float>(bytes);
                break;
            case PlyType::kFloat64:
                *value = Load<double>(bytes);
                break;
        }
        return true;
    }

    template <typename T>
    static double Load(const unsigned char* bytes) {
        T v;
        std::memcpy(&v, bytes, sizeof(T));
        return static_cast<double>(v);
    }

    bool Fail(std::string what) {
        error_ = std::move(what);
        return false;
    }

    const std::string& data_;
    size_t pos_;
    PlyFormat format_;
    std::string error_;
};

// The header's lines up to end_header; *body receives the offset just after it.
std::vector<PlyElement> ParsePlyHeader(const std::string& data, const std::string& path,
                                       PlyFormat* format, size_t* body) {
    auto fail = [&](const std::string& what) -> void {
        throw std::runtime_error(path + ": PLY header: " + what);
    };
    if (data.compare(0, 3, "ply") != 0) fail("the file does not start with 'ply'");
    std::vector<PlyElement> elements;
    bool have_format = false;
    size_t pos = 0;
    int line_no = 0;
    while (true) {
        if (pos >= data.size()) fail("no 'end_header' line");
        size_t eol = data.find('\n', pos);
        if (eol == std::string::npos) eol = data.size();
        std::string line = data.substr(pos, eol - pos);
        pos = eol + 1;
        ++line_no;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream in(line);
        std::string word;
        in >> word;
        std::string at = "line " + std::to_string(line_no) + ": ";
        if (line_no == 1) {
            if (word != "ply") fail("the file does not start with 'ply'");
            continue;
        }
        if (word.empty() || word == "comment" || word == "obj_info") continue;
        if (word == "end_header") break;
        if (word == "format") {
            std::string name, version;
            in >> name >> version;
            if (name == "ascii") {
                *format = PlyFormat::kAscii;
            } else if (name == "binary_little_endian") {
                *format = PlyFormat::kBinaryLittle;
            } else if (name == "binary_big_endian") {
                *format = PlyFormat::kBinaryBig;
            } else {
                fail(at + "unknown format '" + name + "'");
            }
            have_format = true;
        } else if (word == "element") {
            PlyElement e;
            long long count = -1;
            in >> e.name >> count;
            if (e.name.empty() || !in || count < 0) fail(at + "malformed element line");
            e.count = size_t(count);
            elements.push_back(std::move(e));
        } else if (word == "property") {
            if (elements.empty()) fail(at + "property before any element");
            PlyProperty p;
            std::string type;
            in >> type;
            if (type == "list") {
                std::string count_type, item_type;
                in >> count_type >> item_type >> p.name;
                auto ct = ParsePlyType(count_type), it = ParsePlyType(item_type);
                if (!ct || !it)
                    fail(at + "unknown list type '" + count_type + " " + item_type + "'");
                if (*ct == PlyType::kFloat32 || *ct == PlyType::kFloat64)
                    fail(at + "a list count must be an integer type");
                p.is_list = true;
                p.count_type = *ct;
                p.type = *it;
            } else {
                in >> p.name;
                auto t = ParsePlyType(type);
                if (!t) fail(at + "unknown property type '" + type + "'");
                p.type = *t;
            }
            if (p.name.empty()) fail(at + "property without a name");
            elements.back().properties.push_back(std::move(p));
        } else {
            fail(at + "unexpected '" + word + "'");
        }
    }
    if (!have_format) fail("no 'format' line");
    *body = pos;
    return elements;
}

// Which attribute slot a vertex property feeds: x y z nx ny nz u v, or -1.
int PlyVertexSlot(const std::string& name) {
    static const char* kNames[8][3] = {{"x", nullptr, nullptr},  {"y", nullptr, nullptr},
                                       {"z", nullptr, nullptr},  {"nx", nullptr, nullptr},
                                       {"ny", nullptr, nullptr}, {"nz", nullptr, nullptr},
                                       {"u", "s", "texture_u"},  {"v", "t", "texture_v"}};
    for (int s = 0; s < 8; ++s)
        for (const char* n : kNames[s])
            if (n && name == n) return s;
    return -1;
}

TriangleMesh LoadPly(const std::string& path, const std::string& data) {
    PlyFormat format = PlyFormat::kAscii;
    size_t body = 0;
    std::vector<PlyElement> elements = ParsePlyHeader(data, path, &format, &body);

    auto fail = [&](const std::string& what) -> void {
        throw std::runtime_error(path + ": PLY: " + what);
    };
    const PlyElement* vertex = nullptr;
    const PlyElement* face = nullptr;
    for (const PlyElement& e : elements) {
        if (e.name == "vertex") vertex = &e;
        if (e.name == "face") face = &e;
    }
    if (!vertex) fail("no 'vertex' element");
    if (!face) fail("no 'face' element");

    std::vector<int> vertex_slots;
    bool has_slot[8] = {};
    for (const PlyProperty& p : vertex->properties) {
        int s = PlyVertexSlot(p.name);
        if (s >= 0 && p.is_list) fail("vertex property '" + p.name + "' is a list");
        if (s >= 0) has_slot[s] = true;
        vertex_slots.push_back(s);
    }
    if (!has_slot[0] || !has_slot[1] || !has_slot[2]) fail("vertex element lacks x, y or z");
    bool has_normals = has_slot[3] && has_slot[4] && has_slot[5];
    bool has_uvs = has_slot[6] && has_slot[7];
    const PlyProperty* index_list = nullptr;
    for (const PlyProperty& p : face->properties) {
        if (p.name == "vertex_indices" || p.name == "vertex_index") index_list = &p;
    }
    if (!index_list || !index_list->is_list) fail("face element lacks a 'vertex_indices' list");

    TriangleMesh m;
    // The header's count is a claim: every vertex takes at least a byte of the body, so
    // no more than the body's size is reserved (a tiny file cannot claim terabytes).
    const size_t reserve = std::min(vertex->count, data.size() - std::min(body, data.size()));
    m.positions.reserve(reserve);
    if (has_normals) m.normals.reserve(reserve);
    if (has_uvs) m.uvs.reserve(reserve);
    PlyBodyReader reader(data, body, format);
    std::vector<uint32_t> polygon;
    for (const PlyElement& e : elements) {
        // An element without properties has nothing in the body, whatever count it claims
        // (a count of 10^11 would otherwise loop for minutes over nothing).
        if (e.properties.empty()) continue;
        for (size_t i = 0; i < e.count; ++i) {
            double attr[8] = {};
            polygon.clear();
            for (size_t pi = 0; pi < e.properties.size(); ++pi) {
                const PlyProperty& p = e.properties[pi];
                auto read = [&](PlyType type, double* v) {
                    if (!reader.Read(type, v))
                        fail(reader.Error() + " in " + e.name + " " + std::to_string(i) +
                             ", property '" + p.name + "'");
                };
                double v = 0;
                if (!p.is_list) {
                    read(p.type, &v);
                    if (&e == vertex && vertex_slots[pi] >= 0) attr[vertex_slots[pi]] = v;
                    continue;
                }
                double n = 0;
                read(p.count_type, &n);
                if (n < 0) fail(e.name + " " + std::to_string(i) + " has a negative list count");
                // An ASCII count may be written as any integral number ("1e30", "inf").
                if (n > double(UINT32_MAX))
                    fail(e.name + " " + std::to_string(i) + " has a list count over 2^32 - 1");
                bool indices = &e == face && &p == index_list;
                for (size_t k = 0; k < size_t(n); ++k) {
                    read(p.type, &v);
                    if (!indices) continue;
                    // NaN, fractions and huge values (an ASCII "1e30") are refused too;
                    // the index is written as read.
                    if (!(v >= 0 && v < double(vertex->count)) || v != std::floor(v)) {
                        char written[32];
                        std::snprintf(written, sizeof written, "%g", v);
                        fail("face " + std::to_string(i) + " uses vertex " + written +
                             " but there are only " + std::to_string(vertex->count) + " vertices");
                    }
                    polygon.push_back(uint32_t(v));
                }
                if (indices && polygon.size() < 3)
                    fail("face " + std::to_string(i) + " has fewer than 3 vertices");
            }
            if (&e == vertex) {
                m.positions.push_back({float(attr[0]), float(attr[1]), float(attr[2])});
                if (has_normals)
                    m.normals.push_back({float(attr[3]), float(attr[4]), float(attr[5])});
                if (has_uvs) m.uvs.push_back({float(attr[6]), float(attr[7])});
            } else if (&e == face) {
                for (size_t k = 1; k + 1 < polygon.size(); ++k)
                    m.indices.insert(m.indices.end(), {polygon[0], polygon[k], polygon[k + 1]});
            }
        }
    }
    return m;
}

std::string ReadWholeFile(const std::string& path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw std::runtime_error(path + ": is a directory, not a mesh file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path + ": cannot open mesh file: " + std::strerror(errno));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw std::runtime_error(path + ": error reading mesh file");
    return ss.str();
}

std::string LowercaseExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

// `path`'s extension, lowercase, if it names a mesh format.
std::string CheckMeshExtension(const std::string& path) {
    std::string ext = LowercaseExtension(path);
    if (ext != ".obj" && ext != ".ply") {
        throw std::runtime_error(path + ": unsupported mesh format '" + ext +
                                 "' (expected .obj or .ply)");
    }
    return ext;
}

}  // namespace

TriangleMesh LoadMeshFile(const std::string& path) {
    CheckMeshExtension(path);
    // Read first so that a missing file gives the same error for both formats.
    return ParseMeshData(path, ReadWholeFile(path));
}

TriangleMesh ParseMeshData(const std::string& name, const std::string& data) {
    const std::string ext = CheckMeshExtension(name);
    TriangleMesh mesh = ext == ".obj" ? LoadObj(name, data) : LoadPly(name, data);
    if (mesh.NumTriangles() == 0) throw std::runtime_error(name + ": mesh has no triangles");
    try {
        mesh.Validate();
    } catch (const std::runtime_error& e) {
        throw std::runtime_error(name + ": " + e.what());
    }
    return mesh;
}

}  // namespace tessera

#pragma once

// Triangle meshes in object space, and the built-in shapes that become meshes.

#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/transform.h"

namespace tessera {

struct TriangleMesh {
    std::vector<Vec3> positions;
    std::vector<Vec3> normals;      // empty or one per position
    std::vector<Vec2> uvs;          // empty or one per position
    std::vector<uint32_t> indices;  // 3 per triangle

    size_t NumTriangles() const { return indices.size() / 3; }
    void Transform(const tessera::Transform& xf);
    // Throws std::runtime_error describing the first inconsistency (index out of
    // range, attribute count mismatch, non-finite position).
    void Validate() const;
};

// A w x h rectangle in the xy plane centred at the origin, facing +z.
TriangleMesh MakeRectangle(float width, float height);
// A disk of `radius` in the xy plane facing +z, as a fan of `segments` triangles.
TriangleMesh MakeDisk(float radius, int segments = 64);
// An axis-aligned box between lo and hi with outward faces.
TriangleMesh MakeBox(const Vec3& lo, const Vec3& hi);
// A quad from four corners in order (two triangles (0,1,2), (0,2,3)).
TriangleMesh MakeQuad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// Loads an OBJ (tinyobjloader) or PLY file, chosen by extension; all groups merged.
// Throws std::runtime_error with the path and the problem.
TriangleMesh LoadMeshFile(const std::string& path);
// Parses the bytes of an OBJ or PLY file already read, the format chosen by `name`'s
// extension; messages name the file as `name`. Throws std::runtime_error.
TriangleMesh ParseMeshData(const std::string& name, const std::string& data);

}  // namespace tessera

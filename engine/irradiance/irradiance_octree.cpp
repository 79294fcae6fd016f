#include "irradiance/irradiance_octree.h"

#include <cmath>
#include <utility>

namespace tessera {

namespace {

// Below this many halvings of the root, nodes stop splitting: items with a tiny radius
// (records in corners) share the deepest node instead of building a chain of nodes
// down to float resolution. Correct either way, since a node side >= 2R still holds.
constexpr int kMaxDepth = 24;

bool IsFinite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

IrradianceOctree::IrradianceOctree(const Bounds3& bounds) {
    Node root;
    if (!bounds.Empty() && IsFinite(bounds.lo) && IsFinite(bounds.hi)) {
        Vec3 extent = bounds.hi - bounds.lo;
        // A flat or point-like scene still gets a cube with some volume.
        float side = std::max(MaxComponent(extent), 1e-3f * (1 + MaxComponent(Abs(bounds.lo))));
        root.size = side;
        root.lo = bounds.Center() - Vec3(side, side, side) * 0.5f;
        // The halving above rounds; make sure the cube still covers the bounds.
        root.lo = Min(root.lo, bounds.lo);
        root.size = std::max(side, MaxComponent(bounds.hi - root.lo));
    } else {
        root.lo = Vec3(-0.5f, -0.5f, -0.5f);
        root.size = 1;
    }
    nodes_.push_back(std::move(root));
}

bool IrradianceOctree::Contains(const Node& node, const Vec3& p) const {
    for (int a = 0; a < 3; ++a)
        if (p[a] < node.lo[a] || p[a] > node.lo[a] + node.size) return false;
    return true;
}

void IrradianceOctree::GrowToContain(const Vec3& p) {
    while (!Contains(nodes_[root_], p)) {
        const Node& old_root = nodes_[root_];
        Node root;
        root.size = old_root.size * 2;
        int octant = 0;
        for (int a = 0; a < 3; ++a) {
            // Grow towards p: the old root becomes the upper half along axes where p is below.
            if (p[a] < old_root.lo[a]) {
                root.lo[a] = old_root.lo[a] - old_root.size;
                octant |= 1 << a;
            } else {
                root.lo[a] = old_root.lo[a];
            }
        }
        root.children[octant] = root_;
        nodes_.push_back(std::move(root));
        root_ = static_cast<int32_t>(nodes_.size() - 1);
    }
    // Some items that were too large for the old root fit the new one.
    std::vector<Oversize> oversize = std::move(oversize_);
    oversize_.clear();
    for (const Oversize& o : oversize) Insert(o.index, o.p, o.radius);
}

void IrradianceOctree::Insert(uint32_t index, const Vec3& p, float radius) {
    if (!Contains(nodes_[root_], p)) GrowToContain(p);
    // Written so that NaN and infinity land in the oversize list.
    if (!(2 * radius <= nodes_[root_].size)) {
        oversize_.push_back({index, p, radius});
        return;
    }
    InsertInTree(index, p, radius);
}

void IrradianceOctree::InsertInTree(uint32_t index, const Vec3& p, float radius) {
    float need = 2 * radius;
    int32_t current = root_;
    for (int depth = 0; depth < kMaxDepth; ++depth) {
        const Node& node = nodes_[current];
        float half = node.size * 0.5f;
        if (half < need) break;
        // The child's lo is exactly the midpoint compared against, so that the child
        // contains p in the same rounded arithmetic as the query's Reaches().
        int octant = 0;
        Vec3 child_lo = node.lo;
        for (int a = 0; a < 3; ++a) {
            float mid = node.lo[a] + half;
            if (p[a] >= mid) {
                octant |= 1 << a;
                child_lo[a] = mid;
            }
        }
        int32_t child = node.children[octant];
        if (child < 0) {
            Node fresh;
            fresh.lo = child_lo;
            fresh.size = half;
            nodes_.push_back(std::move(fresh));  // invalidates `node`
            child = static_cast<int32_t>(nodes_.size() - 1);
            nodes_[current].children[octant] = child;
        }
        current = child;
    }
    nodes_[current].items.push_back(Item{p, radius * radius, index});
}

}  // namespace tessera

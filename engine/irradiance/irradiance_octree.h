#pragma once

// The lookup structure of the irradiance cache (Ward, Rubinstein, Clear 1988, section 3):
// an octree in which each item, a point with a radius of influence R, is stored at the
// deepest node that contains the point and whose side is at least 2R. A query at q then
// only has to visit the nodes whose cube, grown by half its side on every face, contains q:
// at most two per axis and level, i.e. the path to q and its neighbours. Items are indices
// into the caller's array; the octree never sees the records themselves.
//
// The tree grows (the root doubles towards the point) when an item falls outside it, so
// the initial bounds are a hint, not a limit. Insertion after queries is fine; neither
// is synchronised, so one writer and no concurrent readers while it inserts.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/math.h"

namespace tessera {

class IrradianceOctree {
  public:
    explicit IrradianceOctree(const Bounds3& bounds);

    // `p` must be finite; `radius` >= 0, and may be infinite (an item usable everywhere).
    void Insert(uint32_t index, const Vec3& p, float radius);

    // Calls f(index) for every item with |q - p| < radius, and for some more (a superset:
    // the caller filters by its own, exact, test; only items too large for the tree are
    // passed unfiltered). Thread-safe against other queries.
    template <typename F>
    void ForEachCandidate(const Vec3& q, F&& f) const {
        for (const Oversize& o : oversize_) f(o.index);
        Visit(root_, q, f);
    }

    // Calls f(index) for every item whose sphere of influence meets the box [lo, hi], and
    // for some more: a superset of ForEachCandidate(q) for every q in the box. Thread-safe
    // against other queries.
    template <typename F>
    void ForEachCandidateInBox(const Vec3& lo, const Vec3& hi, F&& f) const {
        for (const Oversize& o : oversize_) f(o.index);
        VisitBox(root_, lo, hi, f);
    }

    // Statistics, for tests and tuning.
    size_t NodeCount() const { return nodes_.size(); }
    float RootSize() const { return nodes_[root_].size; }

  private:
    // An item's point and squared radius live beside its index, so that a query rejects
    // most candidates without touching the caller's (much larger) records.
    struct Item {
        Vec3 p;
        float radius2;
        uint32_t index;
    };
    struct Node {
        Vec3 lo;
        float size = 0;  // side of the cube [lo, lo + size]
        std::array<int32_t, 8> children{-1, -1, -1, -1, -1, -1, -1, -1};
        std::vector<Item> items;
    };
    // Items too large for the root (2R > root side, or R infinite): checked at every query.
    // They keep their point and radius so that a grown root can take them back.
    struct Oversize {
        uint32_t index;
        Vec3 p;
        float radius;
    };

    void GrowToContain(const Vec3& p);
    bool Contains(const Node& node, const Vec3& p) const;
    // Puts an item whose point the root contains and whose 2R fits the root's side.
    void InsertInTree(uint32_t index, const Vec3& p, float radius);

    // Whether the node's cube grown by half its side on each face (the farthest any item
    // stored there can reach) contains q. The slack absorbs the rounding of lo + size,
    // which is relative to the coordinates' magnitude rather than to the node's size.
    static bool Reaches(const Node& node, const Vec3& q) {
        float half = node.size * 0.5f;
        for (int a = 0; a < 3; ++a) {
            float slack = 1e-5f * (node.size + std::abs(node.lo[a]) + std::abs(q[a]));
            if (q[a] < node.lo[a] - half - slack || q[a] > node.lo[a] + node.size + half + slack)
                return false;
        }
        return true;
    }

    // Reaches() for a box: the grown cube meets [lo, hi].
    static bool ReachesBox(const Node& node, const Vec3& lo, const Vec3& hi) {
        float half = node.size * 0.5f;
        for (int a = 0; a < 3; ++a) {
            float slack =
                1e-5f * (node.size + std::abs(node.lo[a]) + std::abs(lo[a]) + std::abs(hi[a]));
            if (hi[a] < node.lo[a] - half - slack || lo[a] > node.lo[a] + node.size + half + slack)
                return false;
        }
        return true;
    }
    // Squared distance from p to the box, shrunk a little so that rounding never makes it
    // exceed the distance to a point inside the box.
    static float BoxDistanceSquared(const Vec3& lo, const Vec3& hi, const Vec3& p) {
        float d2 = 0;
        for (int a = 0; a < 3; ++a) {
            float d = std::max({lo[a] - p[a], 0.0f, p[a] - hi[a]});
            d2 += d * d;
        }
        return d2 * (1 - 1e-5f);
    }
    template <typename F>
    void VisitBox(int32_t index, const Vec3& lo, const Vec3& hi, F& f) const {
        const Node& node = nodes_[index];
        if (!ReachesBox(node, lo, hi)) return;
        for (const Item& item : node.items)
            if (BoxDistanceSquared(lo, hi, item.p) < item.radius2) f(item.index);
        for (int32_t child : node.children)
            if (child >= 0) VisitBox(child, lo, hi, f);
    }
    template <typename F>
    void Visit(int32_t index, const Vec3& q, F& f) const {
        const Node& node = nodes_[index];
        if (!Reaches(node, q)) return;
        for (const Item& item : node.items)
            if (DistanceSquared(q, item.p) < item.radius2) f(item.index);
        for (int32_t child : node.children)
            if (child >= 0) Visit(child, q, f);
    }

    std::vector<Node> nodes_;
    int32_t root_ = 0;
    std::vector<Oversize> oversize_;
};

}  // namespace tessera

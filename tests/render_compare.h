#pragma once

// Comparing renders: means and standard errors of per-pixel values, the pixels that see a
// given material, and a block-by-block test that two unbiased renderers agree.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "film/image.h"
#include "plan/local_runner.h"
#include "scene/scene.h"

namespace tessera::test {

struct Estimate {
    double mean = 0, se = 0;
    size_t n = 0;
};

// Mean and standard error of independent values.
inline Estimate MeanOf(const std::vector<double>& v) {
    Estimate e;
    e.n = v.size();
    if (v.empty()) return e;
    for (double x : v) e.mean += x;
    e.mean /= double(v.size());
    double var = 0;
    for (double x : v) var += (x - e.mean) * (x - e.mean);
    if (v.size() > 1) e.se = std::sqrt(var / double(v.size() - 1) / double(v.size()));
    return e;
}

// The hit of the ray through raster position p, if any.
inline bool CameraHit(const Scene& scene, Vec2 p, SurfaceInteraction* si) {
    return scene.Intersect(scene.GetCamera().GenerateRay(CameraSample{p, Vec2(0.5f, 0.5f), 0}), si);
}

// Pixels by what their area (an 8 x 8 grid over it, and a margin of a quarter pixel) sees:
// with `all`, those whose every point sees a surface of `material`; without, those none of
// whose points does.
inline std::vector<bool> PixelsBySight(const Scene& scene, const Material* material, bool all) {
    const Vec2i res = scene.GetCamera().Resolution();
    std::vector<bool> mask(size_t(res.x) * res.y, true);
    for (int y = 0; y < res.y; ++y)
        for (int x = 0; x < res.x; ++x)
            for (int j = 0; j < 8 && mask[y * res.x + x]; ++j)
                for (int i = 0; i < 8; ++i) {
                    const Vec2 p(x - 0.25f + 1.5f * (i + 0.5f) / 8,
                                 y - 0.25f + 1.5f * (j + 0.5f) / 8);
                    SurfaceInteraction si;
                    const bool sees = CameraHit(scene, p, &si) && si.material == material;
                    if (sees != all) {
                        mask[y * res.x + x] = false;
                        break;
                    }
                }
    return mask;
}

// Pixels that see only `material`: where a light tracer and a path tracer must agree.
// Elsewhere the camera sees specular surfaces (which light paths cannot reach through a
// pinhole) or emitters directly.
inline std::vector<bool> PixelsSeeing(const Scene& scene, const Material* material) {
    return PixelsBySight(scene, material, true);
}

// Pixels that see nothing of `material`: to leave emitters out of a comparison, partly
// covered pixels too (a sliver of a bright light dominates a pixel's value and variance).
inline std::vector<bool> PixelsNotSeeing(const Scene& scene, const Material* material) {
    return PixelsBySight(scene, material, false);
}

// Renders of one job with `count` seeds (the settings' seed, then steps of 101).
inline std::vector<Image> RenderSeeds(const Scene& scene, RenderSettings settings, int count = 8) {
    std::vector<Image> images;
    for (int r = 0; r < count; ++r) {
        images.push_back(RenderFrameLocal(scene, settings, 2));
        settings.seed += 101;
    }
    return images;
}

// The job on two threads and on one: the same bits, finite and not black; another seed:
// another image.
inline void ExpectThreadCountLeavesTheImageBitIdentical(const Scene& scene,
                                                        RenderSettings settings) {
    const Image a = RenderFrameLocal(scene, settings, 2);
    const Image b = RenderFrameLocal(scene, settings, 1);
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    EXPECT_EQ(std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float)), 0);
    double sum = 0;
    for (float v : a.pixels) {
        ASSERT_TRUE(std::isfinite(v));
        sum += v;
    }
    EXPECT_GT(sum, 0);
    settings.seed += 1;
    const Image c = RenderFrameLocal(scene, settings, 2);
    EXPECT_NE(std::memcmp(a.pixels.data(), c.pixels.data(), a.pixels.size() * sizeof(float)), 0);
}

// One renderer's image (`light`) against another's (`path`, the reference), block by block (block x
// block pixels, only the pixels in `mask`): the difference of the two images, pixel by pixel, has
// mean zero, and its pixels are independent, so each block's mean difference is compared with its
// standard error: within max_z of them (3.5 keeps the chance that one of 16 blocks fails
// by chance near 1%), and the whole image's within 3. The test must also be able to see a bias of
// `resolve` (relative): each block's standard error is at most resolve / 4 of its mean. Returns the
// largest |z|.
inline double ExpectBlocksAgree(const Image& light, const Image& path,
                                const std::vector<bool>& mask, int block, double max_z,
                                double resolve, bool verbose = false) {
    EXPECT_EQ(light.width, path.width);
    EXPECT_EQ(light.height, path.height);
    double worst = 0;
    int blocks = 0;
    std::vector<double> all_diff, all_path;
    for (int by = 0; by + block <= light.height; by += block)
        for (int bx = 0; bx + block <= light.width; bx += block) {
            std::vector<double> diff, reference;
            for (int y = by; y < by + block; ++y)
                for (int x = bx; x < bx + block; ++x) {
                    if (!mask[y * light.width + x]) continue;
                    for (int c = 0; c < 3; ++c) {
                        diff.push_back(light.At(x, y, c) - path.At(x, y, c));
                        reference.push_back(path.At(x, y, c));
                    }
                }
            // Blocks mostly outside the mask say little; their pixels still count below.
            all_diff.insert(all_diff.end(), diff.begin(), diff.end());
            all_path.insert(all_path.end(), reference.begin(), reference.end());
            if (diff.size() < size_t(3 * block * block / 2)) continue;
            const Estimate d = MeanOf(diff);
            const double ref = MeanOf(reference).mean;
            // Black in both (the sky): nothing to compare.
            if (ref == 0 && d.mean == 0 && d.se == 0) continue;
            ++blocks;
            const double z = d.se > 0 ? d.mean / d.se : 0;
            worst = std::max(worst, std::abs(z));
            if (verbose)
                std::printf(
                    "    block (%2d,%2d): reference %.4f, difference %+.4f (%+.2f%%), se %.2f%%, "
                    "z %+.2f\n",
                    bx, by, ref, d.mean, 100 * d.mean / ref, 100 * d.se / ref, z);
            EXPECT_LT(std::abs(z), max_z) << "block (" << bx << ", " << by << "): reference " << ref
                                          << ", difference " << d.mean << ", se " << d.se;
            EXPECT_LT(4 * d.se, resolve * ref)
                << "block (" << bx << ", " << by << ") too noisy to resolve " << resolve;
        }
    EXPECT_GE(blocks, 4) << "too few blocks inside the mask";
    const Estimate total = MeanOf(all_diff);
    const double ref = MeanOf(all_path).mean;
    if (verbose)
        std::printf(
            "    all %zu values: difference %+.3f%%, se %.3f%%, %d blocks, worst |z| %.2f\n",
            total.n, 100 * total.mean / ref, 100 * total.se / ref, blocks, worst);
    testing::Test::RecordProperty("relative_difference", std::to_string(total.mean / ref));
    testing::Test::RecordProperty("relative_standard_error", std::to_string(total.se / ref));
    testing::Test::RecordProperty("worst_block_z", std::to_string(worst));
    EXPECT_LT(std::abs(total.mean), 3 * total.se) << "whole image";
    return worst;
}

// Renders made with several seeds (`renders`) against a reference, block by block (only the
// pixels in `mask`): each block's mean difference per render, then its mean and standard
// error over the renders, so that errors correlated between pixels (splats of light
// subpaths) count. Each block within max_t standard errors (5.4 with 8 renders: a chance
// near 0.1% per block under Student's t with 7 degrees of freedom), the whole image within
// max_t too, and each block's standard error at most resolve / 4 of its mean. Returns the
// largest |t|.
inline double ExpectBlocksAgreeOverSeeds(const std::vector<Image>& renders, const Image& reference,
                                         const std::vector<bool>& mask, int block, double max_t,
                                         double resolve, bool verbose = false) {
    const int w = reference.width, h = reference.height;
    double worst = 0;
    int blocks = 0;
    auto check = [&](int x0, int y0, int x1, int y1, const char* what) {
        std::vector<double> per_render;
        double ref = 0;
        size_t n = 0;
        for (const Image& image : renders) {
            double diff = 0;
            ref = 0;
            n = 0;
            for (int y = y0; y < y1; ++y)
                for (int x = x0; x < x1; ++x) {
                    if (!mask[y * w + x]) continue;
                    for (int c = 0; c < 3; ++c) {
                        diff += image.At(x, y, c) - reference.At(x, y, c);
                        ref += reference.At(x, y, c);
                        ++n;
                    }
                }
            per_render.push_back(n ? diff / double(n) : 0);
        }
        // A block mostly outside the mask says little (its pixels still count in the image).
        const bool whole = x1 - x0 == w && y1 - y0 == h;
        if ((!whole && n < size_t(3 * (x1 - x0) * (y1 - y0) / 2)) || n == 0 || !(ref > 0)) return;
        ref /= double(n);
        const Estimate d = MeanOf(per_render);
        const double t = d.se > 0 ? d.mean / d.se : 0;
        worst = std::max(worst, std::abs(t));
        if (verbose)
            std::printf(
                "    %s (%2d,%2d): reference %.4f, difference %+.4f (%+.2f%%), se %.2f%%, "
                "t %+.2f\n",
                what, x0, y0, ref, d.mean, 100 * d.mean / ref, 100 * d.se / ref, t);
        EXPECT_LT(std::abs(t), max_t) << what << " (" << x0 << ", " << y0 << "): reference " << ref
                                      << ", difference " << d.mean << ", se " << d.se;
        EXPECT_LT(4 * d.se, resolve * ref)
            << what << " (" << x0 << ", " << y0 << ") too noisy to resolve " << resolve;
        ++blocks;
    };
    for (int by = 0; by + block <= h; by += block)
        for (int bx = 0; bx + block <= w; bx += block)
            check(bx, by, bx + block, by + block, "block");
    EXPECT_GE(blocks, 4) << "too few blocks inside the mask";
    check(0, 0, w, h, "image");
    testing::Test::RecordProperty("worst_block_t", std::to_string(worst));
    return worst;
}

// The mean of R, G and B over renders of an image that should be uniform, within 4.5
// standard errors of `expected` (7 degrees of freedom: a chance near 0.3% of failing by
// chance), and the test able to see a relative error of `resolve`. Renderers whose paths
// splat (light tracing, BDPT's t = 1 strategies, MLT's chains) make neighbouring pixels'
// errors correlated, so the standard error comes from the spread of 8 independent renders
// (seeds) rather than from the pixels. Returns the mean.
inline double ExpectUniformRenders(const Scene& scene, RenderSettings settings, double expected,
                                   double resolve = 0.01, bool verbose = false) {
    std::vector<double> means;
    for (const Image& image : RenderSeeds(scene, settings)) {
        double sum = 0;
        for (int y = 0; y < image.height; ++y)
            for (int x = 0; x < image.width; ++x)
                for (int c = 0; c < 3; ++c) sum += image.At(x, y, c);
        means.push_back(sum / (3.0 * image.width * image.height));
    }
    const Estimate e = MeanOf(means);
    if (verbose) std::printf("    mean %.5f, se %.5f (expected %.5f)\n", e.mean, e.se, expected);
    testing::Test::RecordProperty("mean", std::to_string(e.mean));
    testing::Test::RecordProperty("standard_error", std::to_string(e.se));
    EXPECT_NEAR(e.mean, expected, 4.5 * e.se + 1e-6);
    EXPECT_LT(4 * e.se, resolve * expected) << "too noisy to resolve " << resolve;
    return e.mean;
}

}  // namespace tessera::test

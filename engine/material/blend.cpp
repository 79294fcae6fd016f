#include "material/blend.h"

#include <algorithm>
#include <utility>

#include "material/materials.h"

namespace tessera {

BlendBsdf::BlendBsdf(const Bsdf* a, const Bsdf* b, float weight)
    : a_(a), b_(b), w_(std::clamp(weight, 0.0f, 1.0f)) {}

// A part of weight zero is never evaluated, so that weights 0 and 1 reproduce the other
// part exactly (and a part's infinities cannot leak through a zero weight).
Rgb BlendBsdf::Eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    Rgb f;
    if (w_ < 1) f += a_->Eval(wo, wi, mode) * (1 - w_);
    if (w_ > 0) f += b_->Eval(wo, wi, mode) * w_;
    return f;
}

float BlendBsdf::Pdf(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    float pdf = 0;
    if (w_ < 1) pdf += (1 - w_) * a_->Pdf(wo, wi, mode);
    if (w_ > 0) pdf += w_ * b_->Pdf(wo, wi, mode);
    return pdf;
}

std::optional<BsdfSample> BlendBsdf::Sample(const Vec3& wo, float uc, Vec2 u,
                                            TransportMode mode) const {
    bool pick_b = uc >= 1 - w_;
    const Bsdf* chosen = pick_b ? b_ : a_;
    const Bsdf* other = pick_b ? a_ : b_;
    float p_chosen = pick_b ? w_ : 1 - w_;
    float uc_chosen = pick_b ? (uc - (1 - w_)) / w_ : uc / (1 - w_);
    uc_chosen = std::clamp(uc_chosen, 0.0f, kOneMinusEpsilon);
    std::optional<BsdfSample> s = chosen->Sample(wo, uc_chosen, u, mode);
    if (!s) return std::nullopt;
    if (s->IsSpecular()) {
        s->f *= p_chosen;
        s->pdf *= p_chosen;
        return s;
    }
    float p_other = 1 - p_chosen;
    s->f *= p_chosen;
    s->pdf *= p_chosen;
    if (p_other > 0) {
        s->f += other->Eval(wo, s->wi, mode) * p_other;
        s->pdf += p_other * other->Pdf(wo, s->wi, mode);
    }
    if (!(s->pdf > 0) || !std::isfinite(s->pdf)) return std::nullopt;
    return s;
}

uint32_t BlendBsdf::Flags() const {
    uint32_t flags = 0;
    if (w_ < 1) flags |= a_->Flags();
    if (w_ > 0) flags |= b_->Flags();
    return flags;
}

Rgb BlendBsdf::Albedo() const {
    Rgb albedo;
    if (w_ < 1) albedo += a_->Albedo() * (1 - w_);
    if (w_ > 0) albedo += b_->Albedo() * w_;
    return albedo;
}

namespace {

class BlendMaterial final : public Material {
  public:
    BlendMaterial(const Material* a, const Material* b, TextureRef weight)
        : a_(a), b_(b), weight_(std::move(weight)) {}

    const Bsdf* GetBsdf(const TextureContext& ctx, ScratchBuffer& arena) const override {
        float w = std::clamp(weight_->Evaluate(ctx).Average(), 0.0f, 1.0f);
        // A part of weight zero is not even built.
        if (w == 0) return a_->GetBsdf(ctx, arena);
        if (w == 1) return b_->GetBsdf(ctx, arena);
        const Bsdf* a = a_->GetBsdf(ctx, arena);
        const Bsdf* b = b_->GetBsdf(ctx, arena);
        return arena.Alloc<BlendBsdf>(a, b, w);
    }

  private:
    const Material* a_;
    const Material* b_;
    TextureRef weight_;
};

}  // namespace

std::unique_ptr<Material> MakeBlendMaterial(const Material* a, const Material* b,
                                            TextureRef weight) {
    return std::make_unique<BlendMaterial>(a, b, std::move(weight));
}

}  // namespace tessera

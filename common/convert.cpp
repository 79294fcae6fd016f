#include "convert.h"

#include <stdexcept>

namespace tessera {

RenderOverrides FromProto(const v1::RenderOptions& o) {
    RenderOverrides r;
    if (o.has_spp()) r.spp = o.spp();
    if (o.has_integrator()) r.integrator = o.integrator();
    if (o.has_max_depth()) r.max_depth = o.max_depth();
    if (o.has_seed()) r.seed = o.seed();
    if (o.has_tile_size()) r.tile_size = o.tile_size();
    if (o.has_width()) r.width = o.width();
    if (o.has_height()) r.height = o.height();
    if (o.has_sampler()) {
        if (o.sampler() == "stratified")
            r.sampler = SamplerType::kStratified;
        else if (o.sampler() == "independent")
            r.sampler = SamplerType::kIndependent;
        else
            throw std::invalid_argument("unknown sampler '" + o.sampler() + "'");
    }
    return r;
}

v1::RenderOptions ToProto(const RenderOverrides& r) {
    v1::RenderOptions o;
    if (r.spp) o.set_spp(*r.spp);
    if (r.integrator) o.set_integrator(*r.integrator);
    if (r.max_depth) o.set_max_depth(*r.max_depth);
    if (r.seed) o.set_seed(*r.seed);
    if (r.tile_size) o.set_tile_size(*r.tile_size);
    if (r.width) o.set_width(*r.width);
    if (r.height) o.set_height(*r.height);
    if (r.sampler)
        o.set_sampler(*r.sampler == SamplerType::kStratified ? "stratified" : "independent");
    return o;
}

}  // namespace tessera

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
    if (o.has_light_paths_per_task()) r.light_paths_per_task = o.light_paths_per_task();
    if (o.has_width()) r.width = o.width();
    if (o.has_height()) r.height = o.height();
    if (o.has_sampler()) {
        r.sampler = ParseSamplerType(o.sampler());
        if (!r.sampler) throw std::invalid_argument("unknown sampler '" + o.sampler() + "'");
    }
    if (o.has_filter()) {
        r.filter = ParseFilterType(o.filter());
        if (!r.filter)
            throw std::invalid_argument("unknown filter '" + o.filter() +
                                        "' (known: box, gaussian, mitchell, tent)");
    }
    if (o.has_filter_sampling()) {
        r.filter_sampling = ParseFilterSampling(o.filter_sampling());
        if (!r.filter_sampling)
            throw std::invalid_argument("unknown filter sampling '" + o.filter_sampling() +
                                        "' (known: splat, importance)");
    }
    if (o.has_time_sampler()) {
        r.time_sampler = ParseTimeSampler(o.time_sampler());
        if (!r.time_sampler)
            throw std::invalid_argument("unknown time sampler '" + o.time_sampler() +
                                        "' (known: stratified, sampler, independent)");
    }
    if (o.has_irradiance_cache()) r.irradiance_cache = o.irradiance_cache();
    if (o.has_photons_global()) r.photons_global = o.photons_global();
    if (o.has_photons_caustic()) r.photons_caustic = o.photons_caustic();
    if (o.has_photon_batches()) r.photon_batches = o.photon_batches();
    if (o.has_ic_accuracy()) r.ic_accuracy = o.ic_accuracy();
    if (o.has_ic_samples()) r.ic_samples = o.ic_samples();
    if (o.has_ic_passes()) r.ic_passes = o.ic_passes();
    if (o.has_ic_gradients()) r.ic_gradients = o.ic_gradients();
    if (o.has_mlt_bootstrap_samples()) r.mlt_bootstrap = o.mlt_bootstrap_samples();
    if (o.has_mlt_chains()) r.mlt_chains = o.mlt_chains();
    if (o.has_mlt_p_large()) r.mlt_p_large = o.mlt_p_large();
    if (o.has_debug()) {
        r.debug = ParseDebugView(o.debug());
        if (!r.debug)
            throw std::invalid_argument("unknown debug view '" + o.debug() +
                                        "' (known: none, photons, records, indirect)");
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
    if (r.light_paths_per_task) o.set_light_paths_per_task(*r.light_paths_per_task);
    if (r.width) o.set_width(*r.width);
    if (r.height) o.set_height(*r.height);
    if (r.sampler) o.set_sampler(SamplerTypeName(*r.sampler));
    if (r.filter) o.set_filter(FilterTypeName(*r.filter));
    if (r.filter_sampling) o.set_filter_sampling(FilterSamplingName(*r.filter_sampling));
    if (r.time_sampler) o.set_time_sampler(TimeSamplerName(*r.time_sampler));
    if (r.irradiance_cache) o.set_irradiance_cache(*r.irradiance_cache);
    if (r.photons_global) o.set_photons_global(*r.photons_global);
    if (r.photons_caustic) o.set_photons_caustic(*r.photons_caustic);
    if (r.photon_batches) o.set_photon_batches(*r.photon_batches);
    if (r.ic_accuracy) o.set_ic_accuracy(*r.ic_accuracy);
    if (r.ic_samples) o.set_ic_samples(*r.ic_samples);
    if (r.ic_passes) o.set_ic_passes(*r.ic_passes);
    if (r.ic_gradients) o.set_ic_gradients(*r.ic_gradients);
    if (r.mlt_bootstrap) o.set_mlt_bootstrap_samples(*r.mlt_bootstrap);
    if (r.mlt_chains) o.set_mlt_chains(*r.mlt_chains);
    if (r.mlt_p_large) o.set_mlt_p_large(*r.mlt_p_large);
    if (r.debug) o.set_debug(DebugViewName(*r.debug));
    return o;
}

}  // namespace tessera

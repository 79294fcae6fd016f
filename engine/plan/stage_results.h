#pragma once

// Byte encodings of the results of photon and irradiance tasks and of the artifacts
// their stages merge into. Little-endian, self-describing (magic number and version);
// decoding checks every size and throws std::runtime_error on malformed bytes.

#include <cstdint>
#include <string>
#include <vector>

#include "irradiance/irradiance_cache.h"
#include "photon/photon_map.h"

namespace tessera {

// An irradiance pass's tile task: the records it created, in creation order.
std::string EncodeIrradianceTaskResult(int task_index, const std::vector<IrradianceRecord>& r);
std::vector<IrradianceRecord> DecodeIrradianceTaskResult(const std::string& bytes, int* task_index);

// The photon stage's artifact: both maps, powers normalised.
std::string EncodePhotonMaps(const std::vector<Photon>& global, const std::vector<Photon>& caustic);
void DecodePhotonMaps(const std::string& bytes, std::vector<Photon>* global,
                      std::vector<Photon>* caustic);

// An MLT bootstrap task: the luminances of states [first, first + count), depths 0..D per
// state (D + 1 = depths), state-major.
struct MltBootstrapTaskResult {
    int task_index = 0;
    int64_t first = 0;
    int depths = 0;
    std::vector<float> weights;
};
std::string EncodeMltBootstrapTask(const MltBootstrapTaskResult& result);
MltBootstrapTaskResult DecodeMltBootstrapTask(const std::string& bytes);

}  // namespace tessera

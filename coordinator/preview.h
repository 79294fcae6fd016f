#pragma once

// The dashboard's live preview of a frame (GET /api/jobs/{id}/frames/{n}/preview.png): a
// DONE frame's written PNG, or, while the frame renders, a PNG assembled from the frame
// stages' task results done so far, with the tiles not done yet left dark. Tiles are
// summed by FrameAssembler exactly as WriteFrame sums them (the missing ones as empty
// tiles) and tonemapped as the written preview is (8-bit sRGB), so the live preview of a
// finished frame is that frame.
//
// A preview is cached per frame until the set of results it was made of changes: polling
// a frame whose tiles did not change costs one database read and no decoding. Making one
// reads and decodes every result of the frame, so a preview is made again no sooner than
// kRefreshCostFactor times as long as the last one took after it: however many pollers,
// previews take at most about 1/(1 + kRefreshCostFactor) of a core per frame watched.

#include <chrono>
#include <cstdint>
#include <list>
#include <mutex>
#include <string>

#include "coordinator.h"
#include "film/image.h"

namespace tessera {

struct FramePreview {
    std::string png;        // the PNG's bytes
    int results_done = 0;   // the frame stages' task results it was made of
    int results_total = 0;  // of that many (0 when unknown: the job is not running)
    bool final = false;     // the written frame's own preview
};

// The frame as far as `in`'s results go: each result whose blob is readable and decodes as
// its task's is added, the others count as not done (their tiles stay dark, their splats
// add nothing). `*used` (if given) receives how many were added.
Image AssemblePartialFrame(const FrameAssemblyInput& in, BlobStore& blobs, int* used = nullptr);

// The image's R, G, B as an 8-bit sRGB PNG (WritePngPreview's encoding), in memory.
std::string EncodePng(const Image& image);

class FramePreviews {
  public:
    static constexpr int kRefreshCostFactor = 4;

    // `coordinator` must outlive this object; at most `capacity` previews are cached.
    explicit FramePreviews(Coordinator& coordinator, size_t capacity = 16);

    // The preview of frame `frame` of `job_id`. Throws CoordinatorError NOT_FOUND for an
    // unknown job or a frame it does not have (INVALID_ARGUMENT for a malformed id). A
    // frame with no result yet, or of a job that is not running (queued, cancelled,
    // failed) whose preview was never made, is dark at the job's resolution.
    FramePreview Get(const std::string& job_id, int frame);

  private:
    struct Entry {
        std::string key;        // job and frame
        std::string signature;  // what the preview was made of
        FramePreview preview;
        std::chrono::steady_clock::time_point made;  // when it was finished
        std::chrono::steady_clock::duration cost{};  // how long it took to make
    };
    // The cached entry for `key`, moved to the front; null if none.
    Entry* Find(const std::string& key);
    void Put(Entry entry);

    Coordinator& coordinator_;
    const size_t capacity_;
    std::mutex mu_;           // one preview is made at a time: polls of it wait for it
    std::list<Entry> cache_;  // most recently used first
};

}  // namespace tessera

#include "preview.h"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>

#include "io/file_bytes.h"
#include "io/image_io.h"
#include "plan/render_plan.h"
#include "sha256.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// A written preview is 8-bit RGB: 16384^2 pixels at most, with PNG's overhead.
constexpr uint64_t kMaxPreviewFileBytes = uint64_t(1) << 30;

// The results of frame stage `stage` in `in`, by task index ("" where none is recorded).
std::vector<std::string> StageHashes(const FrameAssemblyInput& in, int stage, int num_tasks) {
    std::vector<std::string> hashes(num_tasks);
    const std::vector<std::pair<int, std::string>>* results = nullptr;
    if (stage == in.render_stage) results = &in.results;
    for (const FrameAssemblyInput::Contribution& c : in.contributions)
        if (c.stage == stage) results = &c.results;
    if (!results) return hashes;
    for (const auto& [index, hash] : *results)
        if (index >= 0 && index < num_tasks) hashes[index] = hash;
    return hashes;
}

// Adds task `index`'s result from `bytes`; throws if they are not that task's result.
void AddResult(FrameAssembler& assembler, const RenderPlan& plan, int stage, int index,
               const std::string& bytes) {
    if (plan.stages[stage].task_kind == TaskKind::kSplat) {
        SplatResult result = DecodeSplatResult(bytes);
        if (result.task_index != index) throw std::runtime_error("another task's splats");
        assembler.Add(stage, std::move(result));
        return;
    }
    if (stage != plan.RenderStageIndex()) throw std::runtime_error("tiles of another stage");
    TileResult result = DecodeTileResult(bytes);
    if (result.task_index != index) throw std::runtime_error("another task's tile");
    assembler.Add(std::move(result));
}

// What a task that is not done adds: nothing (an empty tile, a black splat buffer).
void AddNothing(FrameAssembler& assembler, const RenderPlan& plan, int stage, int index) {
    if (plan.stages[stage].task_kind == TaskKind::kSplat) {
        SplatResult empty;
        empty.task_index = index;
        empty.resolution = plan.resolution;
        empty.rgb.assign(size_t(plan.resolution.x) * plan.resolution.y * 3, 0.0f);
        assembler.Add(stage, std::move(empty));
        return;
    }
    TileResult empty;
    empty.task_index = index;
    empty.region = plan.tile_regions.at(index);
    empty.data.assign(size_t(empty.region.Width()) * empty.region.Height() * TileFilm::kChannels,
                      0.0f);
    assembler.Add(std::move(empty));
}

Image DarkImage(int width, int height) {
    Image image;
    image.width = std::max(1, width);
    image.height = std::max(1, height);
    image.channels = {"R", "G", "B"};
    image.pixels.assign(size_t(image.width) * image.height * 3, 0.0f);
    return image;
}

// What a preview of `in` is made of: every frame stage's result blobs, in order.
std::string Signature(const FrameAssemblyInput& in, int* total) {
    std::string text;
    auto add = [&](const std::vector<std::pair<int, std::string>>& results) {
        for (const auto& [index, hash] : results) {
            text += fmt::format("{}:{};", index, hash);
            ++*total;
        }
        text += "|";
    };
    for (const FrameAssemblyInput::Contribution& c : in.contributions) add(c.results);
    add(in.results);
    return Sha256Hex(text);
}

}  // namespace

Image AssemblePartialFrame(const FrameAssemblyInput& in, BlobStore& blobs, int* used) {
    const RenderPlan plan = MakeRenderPlan(in.settings.resolution, in.settings);
    FrameAssembler assembler(plan);
    int added = 0;
    // In task order, so that splat buffers are summed as they come, none held back.
    for (int stage : plan.FrameStages()) {
        const int num_tasks = plan.stages[stage].num_tasks;
        const std::vector<std::string> hashes = StageHashes(in, stage, num_tasks);
        for (int index = 0; index < num_tasks; ++index) {
            bool ok = false;
            if (!hashes[index].empty()) {
                try {
                    AddResult(assembler, plan, stage, index, blobs.ReadVerified(hashes[index]));
                    ok = true;
                } catch (const std::exception&) {
                    // Gone (collected, damaged) or not this task's: shown as not done.
                }
            }
            if (ok)
                ++added;
            else
                AddNothing(assembler, plan, stage, index);
        }
    }
    if (used) *used = added;
    return assembler.Assemble();
}

std::string EncodePng(const Image& image) {
    // OpenImageIO's PNG writer writes files; the image I/O module keeps OIIO to itself.
    static std::atomic<uint64_t> counter{0};
    const fs::path path =
        fs::temp_directory_path() / fmt::format("tessera-preview-{}-{}.png", ::getpid(), ++counter);
    WritePngPreview(path.string(), image);
    std::string bytes;
    try {
        bytes = ReadFileBytes(path.string(), kMaxPreviewFileBytes, "the preview");
    } catch (...) {
        std::error_code ignored;
        fs::remove(path, ignored);
        throw;
    }
    std::error_code ignored;
    fs::remove(path, ignored);
    return bytes;
}

FramePreviews::FramePreviews(Coordinator& coordinator, size_t capacity)
    : coordinator_(coordinator), capacity_(std::max<size_t>(1, capacity)) {}

FramePreview FramePreviews::Get(const std::string& job_id, int frame) {
    const v1::JobStatus job = coordinator_.GetJob(job_id);
    const v1::FrameStatus* status = nullptr;
    for (const v1::FrameStatus& f : job.frames())
        if (f.frame() == frame) status = &f;
    if (!status) ThrowError(ErrorCode::kNotFound, fmt::format("{} has no frame {}", job_id, frame));
    if (status->state() == v1::FRAME_STATE_DONE) {
        FramePreview done;
        done.final = true;
        const std::string path = coordinator_.FrameFile(job_id, frame, true);
        try {
            done.png = ReadFileBytes(path, kMaxPreviewFileBytes, path);
        } catch (const std::exception& e) {
            ThrowError(ErrorCode::kNotFound,
                       fmt::format("the preview of {} frame {} cannot be read: {}", job_id, frame,
                                   e.what()));
        }
        return done;
    }

    const std::string key = fmt::format("{}/{}", job_id, frame);
    std::lock_guard lock(mu_);
    const FrameAssemblyInput in = coordinator_.GetScheduler().GetAssemblyInput(job_id, frame);
    if (!in.job_running) {
        // Not running: its results are not read (a queued job has none, a cancelled or
        // failed one keeps the preview last made while it ran).
        if (Entry* cached = Find(key)) return cached->preview;
        FramePreview dark;
        dark.png = EncodePng(DarkImage(job.width(), job.height()));
        Put(Entry{key, "dark", dark, std::chrono::steady_clock::now(), {}});
        return dark;
    }
    int total = 0;
    std::string signature = Signature(in, &total);
    const auto start = std::chrono::steady_clock::now();
    if (Entry* cached = Find(key)) {
        if (cached->signature == signature) return cached->preview;
        // Newer results, but the last preview is too recent for its cost: it stands.
        if (start - cached->made < kRefreshCostFactor * cached->cost) return cached->preview;
    }
    FramePreview preview;
    preview.png = EncodePng(AssemblePartialFrame(in, coordinator_.Blobs(), &preview.results_done));
    preview.results_total = total;
    const auto made = std::chrono::steady_clock::now();
    Put(Entry{key, std::move(signature), preview, made, made - start});
    return preview;
}

FramePreviews::Entry* FramePreviews::Find(const std::string& key) {
    for (auto it = cache_.begin(); it != cache_.end(); ++it) {
        if (it->key != key) continue;
        cache_.splice(cache_.begin(), cache_, it);
        return &cache_.front();
    }
    return nullptr;
}

void FramePreviews::Put(Entry entry) {
    cache_.remove_if([&](const Entry& e) { return e.key == entry.key; });
    cache_.push_front(std::move(entry));
    while (cache_.size() > capacity_) cache_.pop_back();
}

}  // namespace tessera

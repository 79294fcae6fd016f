#pragma once

// Frame assembly off the gRPC threads: when every task of a frame is done, a queue
// thread decodes the tile results from their blobs, sums them in task-index order
// (FrameAssembler: bit-identical to the local runner) and writes
// <output>/<job_id>/<name>.<frame:04>.exr and a PNG preview beside it, both atomically,
// then marks the frame done. At start-up the queue is seeded with frames whose tasks
// are all done but whose EXR was never recorded (the coordinator died in between).
// A tile result that cannot be read back (missing, or its bytes do not match its hash:
// results are stored without fsync, so an OS crash may lose or damage them) sends its
// task back to the queue (it is rendered again; a damaged blob is removed first)
// instead of failing the job; any other error fails the job.

#include <condition_variable>
#include <deque>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "blob_store.h"
#include "scheduler.h"

namespace tessera {

// <output>/<job_id>/<name>.<frame:04>.exr (.png for the preview).
std::string FramePath(const std::string& output_dir, const std::string& job_id,
                      const std::string& name, int frame, bool preview);

// Tile results that could not be read back at assembly (missing or corrupt blobs).
class UnreadableResults : public std::runtime_error {
  public:
    // `tasks`: (task index, its completion count when read).
    UnreadableResults(std::vector<std::pair<int, int>> tasks, const std::string& first_error);
    const std::vector<std::pair<int, int>>& Tasks() const { return tasks_; }

  private:
    std::vector<std::pair<int, int>> tasks_;
};

// Assembles and writes one frame; returns the EXR's path. Throws UnreadableResults
// if tile results cannot be read back, std::exception on anything else (a failed write).
std::string WriteFrame(const FrameAssemblyInput& input, BlobStore& blobs,
                       const std::string& output_dir, int64_t now_ms);

class AssemblyQueue {
  public:
    AssemblyQueue(Scheduler& scheduler, BlobStore& blobs, std::string output_dir,
                  const Clock& clock);
    ~AssemblyQueue();

    // Queues frames left over from before a restart and starts the thread.
    void Start();
    void Enqueue(const std::string& job_id, int frame);
    // Finishes the frame being written, then stops; frames still queued are found
    // again at the next start-up.
    void Stop();
    // Blocks until the queue is empty and no frame is being written (for tests).
    void WaitIdle();

  private:
    void Run();
    void Assemble(const std::string& job_id, int frame);

    Scheduler& scheduler_;
    BlobStore& blobs_;
    std::string output_dir_;
    const Clock& clock_;
    std::mutex mu_;
    std::condition_variable cv_;
    std::deque<std::pair<std::string, int>> queue_;
    std::set<std::pair<std::string, int>> queued_;
    bool busy_ = false;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace tessera

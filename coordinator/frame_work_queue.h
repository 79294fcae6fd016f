#pragma once

// The coordinator's own work on frames, off the gRPC threads: one thread that merges
// artifact stages (when every task of a frame's "photons" or "irradiance-2" stage is
// done: merge the results in task order, store the artifact as a durable blob, record
// it and release the stages that read it, see Scheduler::StageMerged) and assembles
// frames (when every task of the render stage is done: write the EXR and its preview,
// then mark the frame done).
//
// At start-up the queue is seeded with the work a crash left undone: artifact stages
// whose tasks are all done but that were never merged, and frames whose tasks are all
// done but whose EXR was never recorded. Each step is idempotent until it is recorded,
// so doing one again after a crash changes nothing.
//
// A task result that cannot be read back sends its task back to the queue (it runs
// again) instead of failing the job. A write that fails for lack of space (the artifact,
// the frame, the database) fails nothing either: the item is reported to the
// DiskSpaceMonitor and set aside, and while the farm is out of space no item runs; when
// space returns (Resume) the items set aside are queued again. Any other error fails
// the job.
//
// An observer (SetTimingObserver; /metrics sets one) hears how long each merge and each
// frame write took: the work itself (merging and storing the artifact; writing the EXR and
// its preview), measured on a monotonic clock, for the ones that succeeded; it hears of
// one before it is recorded, so a frame that is DONE has been heard of.

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <tuple>

#include "blob_store.h"
#include "disk_space.h"
#include "scheduler.h"

namespace tessera {

// What an observer of the queue's timings hears.
struct FrameWorkTiming {
    enum Kind { kStageMerge, kFrameAssembly } kind = kFrameAssembly;
    std::string stage;  // the merged stage's name ("photons", "irradiance-2"); empty for a frame
    double seconds = 0;
};

class FrameWorkQueue {
  public:
    using TimingObserver = std::function<void(const FrameWorkTiming&)>;

    FrameWorkQueue(Scheduler& scheduler, BlobStore& blobs, std::string output_dir,
                   const Clock& clock, DiskSpaceMonitor& space);
    ~FrameWorkQueue();

    // Queues the work left over from before a restart and starts the thread.
    void Start();
    // Merge stage `stage` of the frame.
    void EnqueueMerge(const std::string& job_id, int frame, int stage);
    // Assemble and write the frame.
    void EnqueueAssembly(const std::string& job_id, int frame);
    // Finishes the item in progress, then stops; items still queued are found again at
    // the next start-up.
    void Stop();
    // Blocks until the queue is empty and nothing is in progress (for tests).
    void WaitIdle();
    // Space has returned: queues again the items set aside for lack of it, and the work
    // the database says is due (merges and assemblies whose tasks are all done).
    void Resume();
    // Items set aside until space returns.
    size_t WaitingForSpace();
    // Replaces the observer (none: an empty function). It is called on the queue's
    // thread, never after this returns, so its owner may go once it has cleared it.
    void SetTimingObserver(TimingObserver observer);

  private:
    static constexpr int kAssemble = -1;             // the "stage" of an assembly item
    using Item = std::tuple<std::string, int, int>;  // job id, frame, stage or kAssemble

    void Enqueue(const Item& item);
    void Run();
    // Runs one item; a NoSpaceError sets it aside.
    void Process(const Item& item);
    void Merge(const std::string& job_id, int frame, int stage);
    void Assemble(const std::string& job_id, int frame);
    void FailJob(const std::string& job_id, const std::string& message);
    void Observe(const FrameWorkTiming& timing);

    Scheduler& scheduler_;
    BlobStore& blobs_;
    std::string output_dir_;
    const Clock& clock_;
    DiskSpaceMonitor& space_;
    std::mutex mu_;
    std::condition_variable cv_;
    std::deque<Item> queue_;
    std::set<Item> queued_;
    std::set<Item> waiting_for_space_;
    bool busy_ = false;
    bool stop_ = false;
    std::thread thread_;
    std::mutex observer_mu_;  // held while the observer is called
    TimingObserver observer_;
};

}  // namespace tessera

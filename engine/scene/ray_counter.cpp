#include "scene/ray_counter.h"

#include <atomic>
#include <mutex>
#include <unordered_set>

namespace tessera {

namespace {

struct Slot {
    // Written by its thread only; read by RaysTraced() from any thread.
    std::atomic<uint64_t> rays{0};
};

// The slots of the threads alive, and what the finished ones counted.
struct Registry {
    std::mutex mu;
    std::unordered_set<Slot*> live;
    uint64_t finished = 0;
};

Registry& TheRegistry() {
    // Never destroyed: threads may still end (and unregister) during static destruction.
    static Registry* registry = new Registry;
    return *registry;
}

// The calling thread's slot, once it has counted: a plain pointer, so that the common
// path needs no check of a thread_local object's construction.
thread_local Slot* t_slot = nullptr;

// Owns the calling thread's slot: registers it, and retires it when the thread ends.
class ThreadSlot {
  public:
    ThreadSlot() {
        Registry& r = TheRegistry();
        std::lock_guard lock(r.mu);
        r.live.insert(&slot_);
    }
    ~ThreadSlot() {
        t_slot = nullptr;
        Registry& r = TheRegistry();
        std::lock_guard lock(r.mu);
        r.finished += slot_.rays.load(std::memory_order_relaxed);
        r.live.erase(&slot_);
    }
    Slot* Get() { return &slot_; }

  private:
    Slot slot_;
};

Slot* RegisterThisThread() {
    thread_local ThreadSlot owner;
    t_slot = owner.Get();
    return t_slot;
}

}  // namespace

void CountRays(uint64_t n) {
    Slot* slot = t_slot;
    if (!slot) [[unlikely]]
        slot = RegisterThisThread();
    // Only this thread writes it: no read-modify-write (and no locked instruction) needed.
    slot->rays.store(slot->rays.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
}

uint64_t ThreadRaysTraced() {
    const Slot* slot = t_slot;
    return slot ? slot->rays.load(std::memory_order_relaxed) : 0;
}

uint64_t RaysTraced() {
    Registry& r = TheRegistry();
    std::lock_guard lock(r.mu);
    uint64_t total = r.finished;
    for (const Slot* slot : r.live) total += slot->rays.load(std::memory_order_relaxed);
    return total;
}

}  // namespace tessera

#include "log_tail.h"

#include <spdlog/details/os.h>
#include <spdlog/pattern_formatter.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <mutex>
#include <string_view>
#include <vector>

namespace tessera {

LogTail::LogTail(size_t capacity)
    : ring_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(capacity)) {}

size_t LogTail::ThisThread() { return spdlog::details::os::thread_id(); }

std::string LogTail::Lines(spdlog::log_clock::time_point since, size_t thread,
                           const std::string& mention) const {
    const std::vector<spdlog::details::log_msg_buffer> messages = ring_->last_raw();
    // The worker's own words, without its name (the coordinator knows whose tail it is).
    spdlog::pattern_formatter formatter("%Y-%m-%d %H:%M:%S.%e [%l] %v");
    std::vector<std::string> lines;  // newest first
    size_t bytes = 0;
    for (auto it = messages.rbegin(); it != messages.rend() && lines.size() < kMaxLines; ++it) {
        // Threads' clocks are read before they queue for the sink: not quite in order.
        if (it->time < since) continue;
        const std::string_view text(it->payload.data(), it->payload.size());
        if (it->thread_id != thread &&
            (mention.empty() || text.find(mention) == std::string_view::npos))
            continue;
        spdlog::memory_buf_t formatted;
        formatter.format(*it, formatted);
        std::string line(formatted.data(), formatted.size());
        while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
        line += '\n';
        if (bytes + line.size() > kMaxBytes) {
            if (!lines.empty()) break;
            line.resize(kMaxBytes - 1);  // a lone line longer than the budget: its start
            line += '\n';
        }
        bytes += line.size();
        lines.push_back(std::move(line));
    }
    std::string tail;
    tail.reserve(bytes);
    for (auto it = lines.rbegin(); it != lines.rend(); ++it) tail += *it;
    return tail;
}

LogTail& InstallLogTail() {
    static std::mutex mu;
    static LogTail* tail = new LogTail();  // for the whole process, never destroyed
    // Every logger replaced: a thread may still hold a raw pointer to one.
    static auto* replaced = new std::vector<std::shared_ptr<spdlog::logger>>();
    std::lock_guard lock(mu);
    std::shared_ptr<spdlog::logger> current = spdlog::default_logger();
    const auto sink = tail->Sink();
    if (std::find(current->sinks().begin(), current->sinks().end(), sink) != current->sinks().end())
        return *tail;
    std::shared_ptr<spdlog::logger> logger = current->clone(current->name());
    logger->sinks().push_back(sink);
    replaced->push_back(current);
    spdlog::set_default_logger(logger);
    return *tail;
}

}  // namespace tessera

#pragma once

// Prometheus metrics of the farm (prometheus-cpp's registry and text format), served as
// /metrics by the coordinator's HTTP server (http_server.h). Gauges are read from the
// coordinator at each scrape; counters accumulate since the coordinator started.

#include <memory>
#include <string>

namespace tessera {

class Coordinator;

class FarmMetrics {
  public:
    // `coordinator` must outlive this object.
    explicit FarmMetrics(Coordinator& coordinator);
    ~FarmMetrics();

    // The metrics in Prometheus' text exposition format (version 0.0.4). Thread-safe.
    std::string Scrape();

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace tessera

#pragma once

// The dashboard's JSON (http_server.h): jobs, workers and job logs as the page reads them.
// Field names are the proto's (tessera.proto), enums are their short names ("RUNNING",
// "DONE"), 64-bit numbers are JSON numbers (exact up to 2^53: times in ms, counts), and a
// few fields are derived for the page (a job's progress and current stage).

#include <nlohmann/json_fwd.hpp>

#include "tessera/v1/tessera.pb.h"

namespace tessera {

// "QUEUED", "RUNNING", ...; "UNSPECIFIED" for anything else.
std::string JobStateName(v1::JobState state);
std::string FrameStateName(v1::FrameState state);

// A job with its frames and recent failures, and for the page: "progress" (0..1 of its
// tasks), "current_frame" (the first frame rendering, else the first not done, else the
// last; -1 without frames) and "stage_label" (that frame's stage, "" once all are done).
nlohmann::json JobJson(const v1::JobStatus& job);
nlohmann::json WorkerJson(const v1::WorkerStatus& worker);
nlohmann::json LogEntryJson(const v1::JobLogEntry& entry);

}  // namespace tessera

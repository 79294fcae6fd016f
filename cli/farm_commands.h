#pragma once

// The commands that use a farm: `submit`, `status`, `watch`, `cancel`, `fetch` (against a
// running coordinator) and `farm` (a coordinator and workers on this machine, for one job).

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "farm_client.h"
#include "movie.h"

namespace tessera {

// Exit statuses besides 0 (done) and 1 (an error, such as a refused request).
inline constexpr int kExitJobFailed = 3;
inline constexpr int kExitJobCancelled = 4;
inline constexpr int kExitInterrupted = 130;

void AddSubmitCommand(CLI::App& app);
// status, watch, cancel and fetch.
void AddJobCommands(CLI::App& app);
void AddFarmCommand(CLI::App& app);

// Follows the job to its end with progress on stderr, then reports how it ended;
// returns the exit status for that end.
int FollowJob(FarmClient& client, const std::string& job_id, const FollowOptions& options);

// Downloads every finished frame of the job into `dir` as <name>.<frame:04>.exr (and
// .png previews if asked), then, if `movie` wants one and two or more frames were
// fetched, the movie preview <name>.mp4 from the frames' previews (downloaded into a
// temporary folder when they were not asked for); returns the paths written. Throws if
// no frame is finished.
std::vector<std::string> FetchFrames(FarmClient& client, const std::string& job_id,
                                     const std::string& dir, bool previews,
                                     const MovieFlags& movie);

}  // namespace tessera

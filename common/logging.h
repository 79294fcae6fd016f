#pragma once

// The log format of the three programs, one for all:
//
//   2025-01-31 12:00:00.123 [tessera-worker render-3] [info] coordinator 10.0.0.2:50051, ...
//
// on stderr: stdout carries only results that scripts read (the job id `tessera submit`
// prints, the paths `tessera fetch` writes).

#include <string>

namespace tessera {

// Makes the default logger `program`'s: the format above, on stderr, at the level set so far.
// `instance` tells processes of one program apart (a worker's name); may be empty. May be
// called again, e.g. once the command line has named the instance.
void SetUpLogging(const std::string& program, const std::string& instance = "");

}  // namespace tessera

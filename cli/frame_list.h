#pragma once

// The frame-list syntax of `--frames` (`tessera render`, `submit` and `farm`): a comma
// list of items, each `A` (one frame), `A-B` (A to B inclusive) or `A-B:step` (A, A+step,
// ... up to B), e.g. "1-9:2,20,30-32". The result is sorted, without duplicates.

#include <string>
#include <vector>

namespace tessera {

// The largest frame number a list may name: the coordinator's bound on frame numbers,
// so that a list the CLI accepts is never refused for its numbers by a farm.
inline constexpr int kMaxListedFrame = 10000000;
// The most frames one list may hold.
inline constexpr int kMaxListedFrames = 100000;

// What `--frames` expects, for error messages and help texts.
inline constexpr const char* kFrameListSyntax = "expected A, A-B, A-B:step or a comma list of them";

// Parses `text`; throws std::invalid_argument with a message that names the syntax and
// the offending item for anything else: empty items, B < A, a step below 1, a number
// above kMaxListedFrame, or more than kMaxListedFrames frames.
std::vector<int> ParseFrameList(const std::string& text);

// "" if `text` parses, else the reason (a CLI11 validator).
std::string CheckFrameList(const std::string& text);

// True when the frames are consecutive numbers (a range A-B), such as every list of one
// frame. `frames` is sorted and without duplicates.
bool IsFrameRange(const std::vector<int>& frames);

}  // namespace tessera

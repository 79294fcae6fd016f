#include "frame_list.h"

#include <cctype>
#include <set>
#include <stdexcept>

namespace tessera {

namespace {

[[noreturn]] void Bad(const std::string& item, const std::string& why) {
    throw std::invalid_argument(std::string(kFrameListSyntax) + ": '" + item + "' " + why);
}

// A frame number: decimal digits only (no sign, no spaces), at most kMaxListedFrame.
int Number(const std::string& digits, const std::string& item) {
    if (digits.empty()) Bad(item, "lacks a number");
    for (char c : digits)
        if (!std::isdigit(static_cast<unsigned char>(c))) Bad(item, "is not made of numbers");
    // Long strings of digits are out of range whatever they hold; stoll cannot overflow.
    if (digits.size() > 9 || std::stoll(digits) > kMaxListedFrame)
        Bad(item, "names a frame above " + std::to_string(kMaxListedFrame));
    return std::stoi(digits);
}

// Adds the frames of one item ("A", "A-B" or "A-B:step") to `frames`.
void AddItem(const std::string& item, std::set<int>& frames) {
    if (item.empty()) Bad(item, "is empty");
    const size_t dash = item.find('-');
    if (dash == std::string::npos) {
        if (item.find(':') != std::string::npos) Bad(item, "has a step but no range");
        frames.insert(Number(item, item));
        return;
    }
    const size_t colon = item.find(':', dash);
    const int first = Number(item.substr(0, dash), item);
    const int last = Number(
        item.substr(dash + 1, colon == std::string::npos ? std::string::npos : colon - dash - 1),
        item);
    int step = 1;
    if (colon != std::string::npos) {
        const std::string s = item.substr(colon + 1);
        if (s.empty()) Bad(item, "lacks a step after ':'");
        for (char c : s)
            if (!std::isdigit(static_cast<unsigned char>(c)))
                Bad(item, "has a step that is not a number");
        if (s.size() > 9 || std::stoll(s) < 1) Bad(item, "has a step below 1 or too large");
        step = std::stoi(s);
    }
    if (last < first) Bad(item, "ends before it starts");
    // Counted before expanding: a huge range is refused without being built.
    const long long count = (static_cast<long long>(last) - first) / step + 1;
    if (count > kMaxListedFrames)
        Bad(item, "holds " + std::to_string(count) + " frames; at most " +
                      std::to_string(kMaxListedFrames) + " are allowed");
    for (long long f = first; f <= last; f += step) frames.insert(static_cast<int>(f));
}

}  // namespace

std::vector<int> ParseFrameList(const std::string& text) {
    if (text.empty()) throw std::invalid_argument(std::string(kFrameListSyntax) + ": empty");
    std::set<int> frames;
    size_t start = 0;
    while (true) {
        const size_t comma = text.find(',', start);
        AddItem(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start),
                frames);
        if (frames.size() > static_cast<size_t>(kMaxListedFrames))
            throw std::invalid_argument("'" + text + "' holds more than " +
                                        std::to_string(kMaxListedFrames) + " frames");
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return {frames.begin(), frames.end()};
}

std::string CheckFrameList(const std::string& text) {
    try {
        ParseFrameList(text);
        return {};
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
}

bool IsFrameRange(const std::vector<int>& frames) {
    return frames.empty() || frames.back() - frames.front() + 1 == static_cast<int>(frames.size());
}

}  // namespace tessera

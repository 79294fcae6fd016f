// The `--frames` syntax: A, A-B, A-B:step and comma lists of them, sorted and without
// duplicates, with errors that name the syntax and the bad item.

#include "frame_list.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace tessera {
namespace {

using Frames = std::vector<int>;

// The message ParseFrameList throws for `text` ("" if it does not throw).
std::string Error(const std::string& text) {
    try {
        ParseFrameList(text);
    } catch (const std::invalid_argument& e) {
        return e.what();
    }
    return "";
}

TEST(FrameListTest, OneFrame) {
    EXPECT_EQ(ParseFrameList("0"), Frames({0}));
    EXPECT_EQ(ParseFrameList("17"), Frames({17}));
    EXPECT_EQ(ParseFrameList("007"), Frames({7}));
}

TEST(FrameListTest, RangeIsInclusive) {
    EXPECT_EQ(ParseFrameList("3-6"), Frames({3, 4, 5, 6}));
    EXPECT_EQ(ParseFrameList("5-5"), Frames({5}));
}

TEST(FrameListTest, RangeWithStep) {
    EXPECT_EQ(ParseFrameList("1-9:2"), Frames({1, 3, 5, 7, 9}));
    EXPECT_EQ(ParseFrameList("0-10:4"), Frames({0, 4, 8})) << "the last step may stop short of B";
    EXPECT_EQ(ParseFrameList("0-2:2"), Frames({0, 2}));
    EXPECT_EQ(ParseFrameList("4-4:3"), Frames({4}));
    EXPECT_EQ(ParseFrameList("2-3:100"), Frames({2}));
}

TEST(FrameListTest, CommaListIsSortedWithoutDuplicates) {
    EXPECT_EQ(ParseFrameList("1-9:2,20,30-32"), Frames({1, 3, 5, 7, 9, 20, 30, 31, 32}));
    EXPECT_EQ(ParseFrameList("30,2,10-11"), Frames({2, 10, 11, 30}));
    EXPECT_EQ(ParseFrameList("5,5,1-6,3"), Frames({1, 2, 3, 4, 5, 6}));
    EXPECT_EQ(ParseFrameList("0-4:2,1-5:2"), Frames({0, 1, 2, 3, 4, 5}));
}

TEST(FrameListTest, MalformedSpecsNameTheSyntaxAndTheItem) {
    for (const std::string bad : {"",      ",",   "1,",    ",1",      "1,,2",  "-",
                                  "-3",    "3-",  "a",     "1-b",     "1.5",   "1 - 3",
                                  " 1",    "+2",  "-1-3",  "1-3:",    "1-3:0", "1-3:-1",
                                  "1-3:x", "1:2", "1-2-3", "1-3:2:1", "6-2",   "1--3"}) {
        const std::string message = Error(bad);
        EXPECT_NE(message, "") << "'" << bad << "' was accepted";
        EXPECT_NE(message.find(kFrameListSyntax), std::string::npos)
            << "'" << bad << "': " << message;
    }
    EXPECT_NE(Error("1,6-2,9").find("'6-2'"), std::string::npos) << Error("1,6-2,9");
    EXPECT_NE(Error("1-3:0").find("step"), std::string::npos) << Error("1-3:0");
}

TEST(FrameListTest, FrameNumbersAreBounded) {
    EXPECT_EQ(ParseFrameList(std::to_string(kMaxListedFrame)), Frames({kMaxListedFrame}));
    EXPECT_NE(Error(std::to_string(kMaxListedFrame + 1)), "");
    EXPECT_NE(Error("99999999999999999999"), "") << "no overflow";
    EXPECT_NE(Error("0-99999999999999999999"), "");
    EXPECT_NE(Error("1-3:99999999999999999999"), "");
}

TEST(FrameListTest, ListLengthIsCapped) {
    const std::string most = "0-" + std::to_string(kMaxListedFrames - 1);
    EXPECT_EQ(ParseFrameList(most).size(), size_t(kMaxListedFrames));
    // The same frames twice are still within the cap.
    EXPECT_EQ(ParseFrameList(most + "," + most).size(), size_t(kMaxListedFrames));
    EXPECT_NE(Error("0-" + std::to_string(kMaxListedFrames)), "");
    EXPECT_NE(Error(most + "," + std::to_string(kMaxListedFrames)), "");
    // Refused by counting, not by building ten million frames.
    EXPECT_NE(Error("0-" + std::to_string(kMaxListedFrame)), "");
    EXPECT_EQ(ParseFrameList("0-" + std::to_string(kMaxListedFrame) + ":1000").size(), 10001u);
}

TEST(FrameListTest, CheckFrameListIsEmptyForGoodSpecs) {
    EXPECT_EQ(CheckFrameList("1-9:2,20"), "");
    EXPECT_NE(CheckFrameList("9-1"), "");
}

TEST(FrameListTest, RangesAreRecognised) {
    EXPECT_TRUE(IsFrameRange(ParseFrameList("4")));
    EXPECT_TRUE(IsFrameRange(ParseFrameList("4-9")));
    EXPECT_TRUE(IsFrameRange(ParseFrameList("4-6,7,8-9")));
    EXPECT_FALSE(IsFrameRange(ParseFrameList("0-4:2")));
    EXPECT_FALSE(IsFrameRange(ParseFrameList("0,2,5")));
}

}  // namespace
}  // namespace tessera

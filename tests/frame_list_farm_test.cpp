// Jobs of listed frames (not one range) on a real farm on 127.0.0.1: the coordinator
// renders exactly the listed frames, `tessera fetch` and `tessera farm` write exactly
// those files and a movie preview of them, and a malformed frame list is refused with
// INVALID_ARGUMENT and a message that says what is wrong.

#include <set>

#include "farm_harness.h"

namespace tessera {
namespace {

using namespace farm_testing;

const std::vector<std::string> kTiny = {"--width", "16", "--height",    "12",
                                        "--spp",   "1",  "--tile-size", "8"};

bool HaveFfmpeg() {
    const char* path = std::getenv("PATH");
    std::string dirs = path ? path : "";
    size_t start = 0;
    while (start <= dirs.size()) {
        size_t end = dirs.find(':', start);
        if (end == std::string::npos) end = dirs.size();
        if (end > start &&
            ::access((dirs.substr(start, end - start) + "/ffmpeg").c_str(), X_OK) == 0)
            return true;
        start = end + 1;
    }
    return false;
}

// The names of the files directly in `dir`.
std::set<std::string> FileNames(const fs::path& dir) {
    std::set<std::string> names;
    for (const fs::directory_entry& e : fs::directory_iterator(dir))
        names.insert(e.path().filename().string());
    return names;
}

void ExpectFrameImage(const fs::path& path, int width, int height) {
    ASSERT_TRUE(fs::exists(path)) << path;
    const Image image = ReadImage(path.string());
    EXPECT_EQ(image.width, width) << path;
    EXPECT_EQ(image.height, height) << path;
}

class FrameListFarmTest : public FarmHarness {
  protected:
    // The Cornell box's bundle, uploaded, as a spec of frames `frames` (frame_start and
    // frame_end as a client sets them: the list's first and last).
    v1::JobSpec CornellSpec(Stubs& s, const std::vector<int>& frames) {
        EXPECT_TRUE(s.WaitConnected()) << "no connection to the coordinator";
        v1::JobSpec spec;
        spec.set_name("cornell");
        for (const BundleEntry& e : CollectBundle(kCornell)) {
            EXPECT_EQ(UploadFile(*s.blobs, e.local_path), e.hash);
            if (spec.scene_path().empty()) spec.set_scene_path(e.path);
            v1::BundleFile* f = spec.add_files();
            f->set_path(e.path);
            f->set_hash(e.hash);
            f->set_size(e.size);
        }
        *spec.mutable_options() = OptionsFromArgs(kTiny);
        spec.set_frame_start(frames.empty() ? 0 : frames.front());
        spec.set_frame_end(frames.empty() ? 0 : frames.back());
        for (int f : frames) spec.add_frames(f);
        return spec;
    }

    grpc::Status Submit(Stubs& s, const v1::JobSpec& spec, std::string* job_id = nullptr) {
        Ctx ctx(120s);
        v1::SubmitJobRequest req;
        *req.mutable_spec() = spec;
        v1::SubmitJobResponse resp;
        grpc::Status st = s.farm->SubmitJob(&ctx, req, &resp);
        if (job_id) *job_id = resp.job_id();
        return st;
    }

    std::string Address() const { return "127.0.0.1:" + std::to_string(port_); }

    int port_ = 0;
};

TEST_F(FrameListFarmTest, SubmittedFrameListRendersExactlyThoseFrames) {
    port_ = StartCoordinator("state");
    ASSERT_GT(port_, 0);
    StartWorker(port_, "w1");
    StartWorker(port_, "w2");
    CliResult submit = Cli(Concat(
        {"submit", kCornell, "--coordinator", Address(), "--name", "cornell", "--frames", "5,0,2"},
        kTiny));
    ASSERT_EQ(submit.code, 0) << submit.err;
    const std::string job = Trim(submit.out);
    ASSERT_FALSE(job.empty()) << submit.err;

    Stubs s(port_);
    v1::JobStatus last;
    ASSERT_TRUE(WaitDone(s, job, &last));
    std::vector<int> frames;
    for (const v1::FrameStatus& f : last.frames()) frames.push_back(f.frame());
    EXPECT_EQ(frames, std::vector<int>({0, 2, 5})) << last.ShortDebugString();

    const fs::path out = dir_ / "fetched";
    CliResult fetch = Cli({"fetch", job, "-o", out.string(), "--coordinator", Address()});
    ASSERT_EQ(fetch.code, 0) << fetch.err;
    std::set<std::string> expected = {"cornell.0000.exr", "cornell.0002.exr", "cornell.0005.exr"};
    if (HaveFfmpeg()) {
        expected.insert("cornell.mp4");
    } else {
        EXPECT_NE(fetch.err.find("ffmpeg not found"), std::string::npos) << fetch.err;
    }
    // Exactly the listed frames, and no previews left from making the movie.
    EXPECT_EQ(FileNames(out), expected) << fetch.err;
    for (const char* name : {"cornell.0000.exr", "cornell.0002.exr", "cornell.0005.exr"})
        ExpectFrameImage(out / name, 16, 12);
    if (HaveFfmpeg()) {
        EXPECT_GT(fs::file_size(out / "cornell.mp4"), 0u);
    }
}

TEST_F(FrameListFarmTest, FarmCommandRendersAStepRangeAndItsMovie) {
    const fs::path out = dir_ / "frames";
    CliResult r = Cli(Concat({"farm", kCornell, "-q", "--workers", "2", "--threads-per-worker", "1",
                              "--name", "box", "--frames", "0-4:4", "-o", out.string()},
                             kTiny));
    ASSERT_EQ(r.code, 0) << r.err;
    std::set<std::string> expected = {"box.0000.exr", "box.0000.png", "box.0004.exr",
                                      "box.0004.png"};
    if (HaveFfmpeg()) expected.insert("box.mp4");
    EXPECT_EQ(FileNames(out), expected) << r.err;
    ExpectFrameImage(out / "box.0000.exr", 16, 12);
    ExpectFrameImage(out / "box.0004.exr", 16, 12);
}

// An animation with motion blur (moving shapes and camera, an open shutter): four frames
// rendered by a local farm of three workers equal `tessera render`'s, bit for bit, and the
// frames differ from one another.
TEST_F(FrameListFarmTest, AnimatedFramesOnTheFarmMatchLocalRenders) {
    const std::string scene =
        std::string(TESSERA_SOURCE_DIR) + "/scenes/animated-cornell/scene.json";
    const std::vector<std::string> small = {"--width", "32", "--height",    "32",
                                            "--spp",   "2",  "--tile-size", "8"};
    const fs::path farm_out = dir_ / "farm", local_out = dir_ / "local";
    CliResult farm =
        Cli(Concat({"farm", scene, "-q", "--workers", "3", "--threads-per-worker", "1", "--name",
                    "anim", "--frames", "0-3", "--no-movie", "-o", farm_out.string()},
                   small));
    ASSERT_EQ(farm.code, 0) << farm.err;
    fs::create_directories(local_out);
    CliResult local = Cli(Concat({"render", scene, "-q", "--frames", "0-3", "--no-movie", "-o",
                                  (local_out / "anim.exr").string()},
                                 small));
    ASSERT_EQ(local.code, 0) << local.err;
    std::vector<float> previous;
    for (int f = 0; f < 4; ++f) {
        const std::string name = "anim.000" + std::to_string(f) + ".exr";
        const Image a = ReadImage((farm_out / name).string());
        const Image b = ReadImage((local_out / name).string());
        ASSERT_EQ(a.pixels.size(), b.pixels.size()) << name;
        EXPECT_TRUE(a.pixels == b.pixels)
            << name << ": the farm's frame differs from the local one";
        EXPECT_FALSE(a.pixels == previous) << name << " is the same as the frame before";
        previous = a.pixels;
    }
}

TEST_F(FrameListFarmTest, MalformedFrameListsAreRefusedWithAReason) {
    port_ = StartCoordinator("state");
    ASSERT_GT(port_, 0);
    Stubs s(port_);
    struct Case {
        std::vector<int> frames;
        std::string message;
    };
    for (const Case& c : std::vector<Case>{{{5, 2, 7}, "not sorted"},
                                           {{1, 3, 3}, "frame 3 is listed twice"},
                                           {{-2, 4}, "is negative"},
                                           {{0, 10000001}, "beyond the last frame number"}}) {
        grpc::Status st = Submit(s, CornellSpec(s, c.frames));
        EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
            << c.message << ": " << StatusText(st);
        EXPECT_NE(st.error_message().find(c.message), std::string::npos) << st.error_message();
    }
    // Too many frames for the coordinator's limit.
    std::vector<int> many;
    for (int f = 0; f <= 10000; ++f) many.push_back(f * 2);
    grpc::Status st = Submit(s, CornellSpec(s, many));
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << StatusText(st);
    EXPECT_NE(st.error_message().find("frames listed"), std::string::npos) << st.error_message();

    // A well-formed list is accepted, with its ends as the job's range.
    std::string job;
    st = Submit(s, CornellSpec(s, {1, 4}), &job);
    ASSERT_TRUE(st.ok()) << StatusText(st);
    Ctx ctx;
    v1::GetJobRequest req;
    req.set_job_id(job);
    v1::JobStatus status;
    ASSERT_TRUE(s.farm->GetJob(&ctx, req, &status).ok());
    ASSERT_EQ(status.frames_size(), 2);
    EXPECT_EQ(status.frames(0).frame(), 1);
    EXPECT_EQ(status.frames(1).frame(), 4);
}

}  // namespace
}  // namespace tessera

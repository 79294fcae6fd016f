#include "movie.h"

#include <spdlog/spdlog.h>
#include <stdlib.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "child_process.h"
#include "command_line.h"

namespace tessera {

namespace fs = std::filesystem;

namespace {

// Encoding a long movie of large frames takes a while; this only bounds a hung ffmpeg.
constexpr auto kEncodeTimeout = std::chrono::hours(2);

// A temporary folder, removed with its contents when the object goes.
class TempDir {
  public:
    TempDir() {
        std::string pattern = (fs::temp_directory_path() / "tessera-movie-XXXXXX").string();
        if (!mkdtemp(pattern.data()))
            throw std::runtime_error("cannot create a folder in " +
                                     fs::temp_directory_path().string());
        path_ = pattern;
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    const fs::path& Path() const { return path_; }

  private:
    fs::path path_;
};

std::string ReadText(const fs::path& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    std::string s = text.str();
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    return s;
}

}  // namespace

void MovieFlags::AddTo(CLI::App& cmd) {
    cmd.add_option("--fps", fps, "Frames per second of the MP4 movie preview")
        ->check(InRange(0.1, 1000.0))
        ->capture_default_str();
    cmd.add_flag("--no-movie", no_movie,
                 "No MP4 movie preview (<name>.mp4, made with ffmpeg from the PNG previews "
                 "when two or more frames are written)");
}

bool WriteMoviePreview(const std::vector<std::string>& images, const std::string& output,
                       double fps) {
    const std::string ffmpeg = FindSiblingProgram(".", "ffmpeg");
    if (ffmpeg.empty()) {
        spdlog::warn("movie preview skipped: ffmpeg not found (apt-get install ffmpeg)");
        return false;
    }
    if (images.empty()) return false;
    try {
        TempDir temp;
        // Links numbered 0..n-1 give ffmpeg's image sequence reader a gapless sequence
        // whatever the frame numbers are.
        const std::string ext = fs::path(images.front()).extension().string();
        for (size_t i = 0; i < images.size(); ++i) {
            char name[32];
            std::snprintf(name, sizeof name, "%06zu", i);
            fs::create_symlink(fs::absolute(images[i]), temp.Path() / (name + ext));
        }
        const fs::path log = temp.Path() / "ffmpeg.log";
        const fs::path partial = temp.Path() / ("movie" + fs::path(output).extension().string());
        char rate[32];
        std::snprintf(rate, sizeof rate, "%g", fps);
        ChildProcess encoder(
            {ffmpeg, "-y", "-loglevel", "error", "-framerate", rate, "-i",
             (temp.Path() / ("%06d" + ext)).string(), "-c:v", "libx264", "-pix_fmt", "yuv420p",
             "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", partial.string()},
            log.string());
        const auto deadline = std::chrono::steady_clock::now() + kEncodeTimeout;
        while (encoder.Running() && std::chrono::steady_clock::now() < deadline)
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        if (encoder.Running()) {
            encoder.Terminate();
            encoder.Wait(std::chrono::milliseconds(5000));
            spdlog::warn("movie preview skipped: ffmpeg did not finish within {} minutes",
                         std::chrono::duration_cast<std::chrono::minutes>(kEncodeTimeout).count());
            return false;
        }
        if (encoder.ExitText() != "exited with status 0") {
            spdlog::warn("movie preview skipped: ffmpeg {}: {}", encoder.ExitText(), ReadText(log));
            return false;
        }
        // Written aside and moved in place: a failed encoding never leaves half a movie.
        std::error_code ec;
        fs::rename(partial, output, ec);
        if (ec) {
            fs::copy_file(partial, output, fs::copy_options::overwrite_existing, ec);
            if (ec) {
                spdlog::warn("movie preview skipped: cannot write {}: {}", output, ec.message());
                return false;
            }
        }
    } catch (const std::exception& e) {
        spdlog::warn("movie preview skipped: {}", e.what());
        return false;
    }
    spdlog::info("wrote {} ({} frames at {:g} fps)", output, images.size(), fps);
    return true;
}

bool MaybeWriteMoviePreview(const MovieFlags& flags, const std::vector<std::string>& images,
                            const std::string& output) {
    if (flags.no_movie || images.size() < 2) return false;
    return WriteMoviePreview(images, output, flags.fps);
}

}  // namespace tessera

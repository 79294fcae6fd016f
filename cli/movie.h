#pragma once

// A movie preview of rendered frames: an H.264 MP4 made by ffmpeg from the frames' RGB
// previews (the PNGs beside the EXRs), so that an animation can be watched at once.
// The frames are what a render produces; the movie is a convenience: a missing or
// failing ffmpeg is a warning, never an error, and never touches the frames.

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace tessera {

// `--fps` and `--no-movie`, as `render`, `farm` and `fetch` take them.
struct MovieFlags {
    double fps = 24;
    bool no_movie = false;

    void AddTo(CLI::App& cmd);
};

// Writes `output` (an .mp4) from `images`, in order, one movie frame each, at `fps`
// frames per second. The images may be numbered with gaps or not at all: ffmpeg reads
// them through links numbered 0..n-1 in a temporary folder. Returns true when the movie
// was written; otherwise logs one warning (ffmpeg not found, or its error output) and
// returns false.
bool WriteMoviePreview(const std::vector<std::string>& images, const std::string& output,
                       double fps);

// The movie preview of a command's frames, if `flags` want one and there are at least
// two frames: WriteMoviePreview into `output`. Returns true when a movie was written.
bool MaybeWriteMoviePreview(const MovieFlags& flags, const std::vector<std::string>& images,
                            const std::string& output);

}  // namespace tessera

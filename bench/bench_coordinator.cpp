// Coordinator throughput: W concurrent fake workers lease trivial tile tasks and
// complete them with a minimal valid result, as fast as the coordinator allows. The
// result travels inline with CompleteTask, as real workers send small results; with
// --upload-blobs it is uploaded as a blob first (FindMissingBlobs + PutBlob).
//
//   bench_coordinator --coordinator HOST:PORT [--workers 8] [--seconds 20] [--upload-blobs]
//
// The job must exist already (bench/run_farm.sh submits one with 1x1-pixel tiles and a
// box filter, so every result is a 1x1 region). Prints tasks/s.

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "blob_client.h"
#include "film/film.h"
#include "plan/render_plan.h"
#include "tessera/v1/tessera.grpc.pb.h"

using namespace tessera;

int main(int argc, char** argv) {
    std::string address;
    int workers = 8;
    double seconds = 20;
    bool upload_blobs = false;
    bool usage = false;
    for (int i = 1; i < argc; ++i) {
        const bool has_value = i + 1 < argc;
        if (!std::strcmp(argv[i], "--upload-blobs"))
            upload_blobs = true;
        else if (!std::strcmp(argv[i], "--coordinator") && has_value)
            address = argv[++i];
        else if (!std::strcmp(argv[i], "--workers") && has_value)
            workers = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--seconds") && has_value)
            seconds = std::atof(argv[++i]);
        else
            usage = true;
    }
    if (address.empty() || usage) {
        std::fprintf(stderr,
                     "usage: bench_coordinator --coordinator HOST:PORT [--workers N] "
                     "[--seconds S] [--upload-blobs]\n");
        return 2;
    }
    auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
    std::atomic<uint64_t> completed{0}, failed{0};
    std::atomic<bool> stop{false};
    auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w) {
        threads.emplace_back([&, w] {
            auto stub = v1::Workers::NewStub(channel);
            auto blobs = v1::BlobStore::NewStub(channel);
            v1::RegisterRequest reg;
            reg.set_name("bench-" + std::to_string(w));
            reg.set_threads(1);
            v1::RegisterResponse reg_resp;
            grpc::ClientContext reg_ctx;
            if (!stub->Register(&reg_ctx, reg, &reg_resp).ok()) {
                ++failed;
                return;
            }
            while (!stop) {
                grpc::ClientContext ctx;
                v1::LeaseTaskRequest req;
                req.set_worker_id(reg_resp.worker_id());
                req.set_wait_ms(1000);
                v1::LeaseTaskResponse resp;
                if (!stub->LeaseTask(&ctx, req, &resp).ok()) {
                    ++failed;
                    continue;
                }
                if (!resp.has_task()) break;  // queue drained
                const v1::Task& t = resp.task();
                // A 1x1 tile at the task's position in a row-major grid of 1x1 tiles.
                TileResult r;
                r.task_index = t.task_index();
                int width = 1;
                if (t.spec().options().has_width()) width = t.spec().options().width();
                int x = t.task_index() % width, y = t.task_index() / width;
                r.region = PixelBounds{Vec2i(x, y), Vec2i(x + 1, y + 1)};
                r.data.assign(TileFilm::kChannels, 0.0f);
                grpc::ClientContext cctx;
                v1::CompleteTaskRequest creq;
                creq.set_worker_id(reg_resp.worker_id());
                creq.set_task_id(t.task_id());
                creq.set_lease_id(t.lease_id());
                creq.set_lease_token(t.lease_token());
                if (upload_blobs)
                    creq.set_result_hash(UploadBlob(*blobs, EncodeTileResult(r)));
                else
                    creq.set_result(EncodeTileResult(r));
                v1::CompleteTaskResponse cresp;
                if (stub->CompleteTask(&cctx, creq, &cresp).ok())
                    ++completed;
                else
                    ++failed;
                if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
                        .count() > seconds)
                    stop = true;
            }
        });
    }
    for (auto& t : threads) t.join();
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "coordinator: %d workers, %llu tasks leased+completed in %.2f s = %.0f tasks/s "
        "(%llu failed calls; results %s)\n",
        workers, (unsigned long long)completed.load(), s, completed / s,
        (unsigned long long)failed.load(), upload_blobs ? "uploaded as blobs" : "inline");
    return 0;
}

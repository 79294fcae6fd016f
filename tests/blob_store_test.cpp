// Blob store tests: put and read back, verification against the claimed hash and size
// with nothing left behind on a mismatch, idempotent and concurrent puts, unsynced
// (recomputable) blobs and the removal of a damaged one on a verified read.

#include "blob_store.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>
#include <vector>

#include "errors.h"
#include "sha256.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

class BlobStoreTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("tessera_blobs_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    // Every file under the store (blobs and temporaries).
    std::vector<std::string> Files() const {
        std::vector<std::string> out;
        for (const auto& e : fs::recursive_directory_iterator(dir_))
            if (e.is_regular_file()) out.push_back(fs::relative(e.path(), dir_).string());
        return out;
    }
    ErrorCode CodeOf(const std::function<void()>& f) {
        try {
            f();
        } catch (const CoordinatorError& e) {
            return e.Code();
        }
        ADD_FAILURE() << "no error";
        return ErrorCode::kInternal;
    }

    fs::path dir_;
};

TEST_F(BlobStoreTest, PutThenReadBack) {
    BlobStore store(dir_.string());
    const std::string bytes = "hello, tiles";
    const std::string hash = Sha256Hex(bytes);
    EXPECT_FALSE(store.Has(hash));
    EXPECT_TRUE(store.Put(hash, bytes));
    EXPECT_TRUE(store.Has(hash));
    EXPECT_EQ(store.Size(hash), bytes.size());
    EXPECT_EQ(store.Read(hash), bytes);
    EXPECT_EQ(store.PathOf(hash), (dir_ / hash.substr(0, 2) / hash).string());
    EXPECT_TRUE(fs::is_regular_file(store.PathOf(hash)));
    EXPECT_EQ(Files(), std::vector<std::string>{hash.substr(0, 2) + "/" + hash});
}

TEST_F(BlobStoreTest, EmptyAndChunkedBlobs) {
    BlobStore store(dir_.string());
    EXPECT_TRUE(store.Put(Sha256Hex(""), ""));
    EXPECT_EQ(store.Read(Sha256Hex("")), "");
    std::string big(3 << 20, 'x');
    for (size_t i = 0; i < big.size(); i += 4093) big[i] = char(i);
    const std::string hash = Sha256Hex(big);
    auto writer = store.BeginWrite(hash, big.size());
    for (size_t at = 0; at < big.size(); at += 1 << 20) writer->Append(big.substr(at, 1 << 20));
    EXPECT_TRUE(writer->Commit());
    EXPECT_EQ(store.Read(hash), big);
}

TEST_F(BlobStoreTest, HashMismatchIsDataLossAndLeavesNothing) {
    BlobStore store(dir_.string());
    const std::string claimed = Sha256Hex("what was promised");
    EXPECT_EQ(CodeOf([&] { store.Put(claimed, "what arrived!!!!!"); }), ErrorCode::kDataLoss);
    EXPECT_FALSE(store.Has(claimed));
    EXPECT_TRUE(Files().empty());
}

TEST_F(BlobStoreTest, SizeMismatchIsDataLossAndLeavesNothing) {
    BlobStore store(dir_.string());
    const std::string bytes = "twelve bytes";
    const std::string hash = Sha256Hex(bytes);
    {
        auto writer = store.BeginWrite(hash, bytes.size() + 1);  // short
        writer->Append(bytes);
        EXPECT_EQ(CodeOf([&] { writer->Commit(); }), ErrorCode::kDataLoss);
    }
    {
        auto writer = store.BeginWrite(hash, bytes.size() - 1);  // long
        EXPECT_EQ(CodeOf([&] { writer->Append(bytes); }), ErrorCode::kDataLoss);
    }
    EXPECT_FALSE(store.Has(hash));
    EXPECT_TRUE(Files().empty());
}

TEST_F(BlobStoreTest, AbandonedUploadLeavesNothing) {
    BlobStore store(dir_.string());
    const std::string hash = Sha256Hex("abandoned");
    {
        auto writer = store.BeginWrite(hash, 9);
        writer->Append("aband");
    }
    EXPECT_TRUE(Files().empty());
}

TEST_F(BlobStoreTest, MalformedHashAndLimits) {
    BlobStore store(dir_.string(), 100);
    EXPECT_EQ(CodeOf([&] { store.Put("ABC", "x"); }), ErrorCode::kInvalidArgument);
    EXPECT_EQ(CodeOf([&] { store.Put(std::string(64, 'G'), "x"); }), ErrorCode::kInvalidArgument);
    EXPECT_EQ(CodeOf([&] { store.Read("../../etc/passwd"); }), ErrorCode::kInvalidArgument);
    EXPECT_EQ(CodeOf([&] { store.Read(Sha256Hex("absent")); }), ErrorCode::kNotFound);
    EXPECT_EQ(CodeOf([&] { store.BeginWrite(Sha256Hex("x"), 101); }),
              ErrorCode::kResourceExhausted);
    EXPECT_FALSE(store.Has("not-a-hash"));
}

TEST_F(BlobStoreTest, PutIsIdempotent) {
    BlobStore store(dir_.string());
    const std::string bytes = "same bytes twice";
    const std::string hash = Sha256Hex(bytes);
    EXPECT_TRUE(store.Put(hash, bytes));
    EXPECT_FALSE(store.Put(hash, bytes));
    EXPECT_EQ(store.Read(hash), bytes);
    EXPECT_EQ(Files().size(), 1u);
}

TEST_F(BlobStoreTest, ConcurrentPutsOfTheSameBlob) {
    BlobStore store(dir_.string());
    std::string bytes(256 << 10, 'q');
    for (size_t i = 0; i < bytes.size(); i += 97) bytes[i] = char(i * 7);
    const std::string hash = Sha256Hex(bytes);
    std::vector<std::thread> threads;
    std::atomic<int> errors{0};
    for (int t = 0; t < 8; ++t) {
        threads.emplace_back([&] {
            try {
                auto writer = store.BeginWrite(hash, bytes.size());
                for (size_t at = 0; at < bytes.size(); at += 8192)
                    writer->Append(std::string_view(bytes).substr(at, 8192));
                writer->Commit();
            } catch (...) {
                ++errors;
            }
        });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(errors.load(), 0);
    EXPECT_EQ(store.Read(hash), bytes);
    EXPECT_EQ(Files().size(), 1u);  // one blob, no temporaries
}

TEST_F(BlobStoreTest, RecomputableBlobsAreStoredAndReadLikeOthers) {
    BlobStore store(dir_.string());
    const std::string bytes = "a tile result, not synced";
    const std::string hash = Sha256Hex(bytes);
    EXPECT_EQ(CodeOf([&] { store.Put(Sha256Hex("other"), bytes, Durability::kRecomputable); }),
              ErrorCode::kDataLoss);
    EXPECT_TRUE(store.Put(hash, bytes, Durability::kRecomputable));
    EXPECT_FALSE(store.Put(hash, bytes, Durability::kRecomputable));
    EXPECT_EQ(store.Read(hash), bytes);
    EXPECT_EQ(store.ReadVerified(hash), bytes);
    EXPECT_EQ(Files(), std::vector<std::string>{hash.substr(0, 2) + "/" + hash});
}

TEST_F(BlobStoreTest, ReadVerifiedRemovesADamagedBlob) {
    BlobStore store(dir_.string());
    const std::string bytes = "bytes an OS crash may lose";
    const std::string hash = Sha256Hex(bytes);
    store.Put(hash, bytes, Durability::kRecomputable);
    // What an unsynced file may look like after a crash: right size, wrong bytes.
    std::string damaged = bytes;
    damaged[5] ^= 0x20;
    { std::ofstream(store.PathOf(hash), std::ios::binary | std::ios::trunc) << damaged; }
    EXPECT_EQ(store.Read(hash), damaged);  // Read does not check
    EXPECT_EQ(CodeOf([&] { store.ReadVerified(hash); }), ErrorCode::kDataLoss);
    EXPECT_FALSE(store.Has(hash));
    EXPECT_EQ(CodeOf([&] { store.ReadVerified(hash); }), ErrorCode::kNotFound);
    EXPECT_TRUE(store.Put(hash, bytes, Durability::kRecomputable));  // stored again
    EXPECT_EQ(store.ReadVerified(hash), bytes);
    EXPECT_EQ(CodeOf([&] { store.ReadVerified("../x"); }), ErrorCode::kInvalidArgument);
}

TEST_F(BlobStoreTest, RestartRemovesStaleTemporaries) {
    const std::string hash = Sha256Hex("partial upload");
    const fs::path shard = dir_ / hash.substr(0, 2);
    fs::create_directories(shard);
    { std::ofstream(shard / (hash + ".123.0.tmp")) << "partial"; }
    BlobStore store(dir_.string());
    EXPECT_TRUE(Files().empty());
    EXPECT_FALSE(store.Has(hash));
}

TEST_F(BlobStoreTest, MaterializePlacesACopy) {
    BlobStore store(dir_.string());
    const std::string bytes = "{\"scene\": true}";
    const std::string hash = Sha256Hex(bytes);
    store.Put(hash, bytes);
    const fs::path dest = dir_ / "job" / "bundle" / "sub" / "scene.json";
    store.Materialize(hash, dest.string());
    std::ifstream in(dest);
    std::string read((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(read, bytes);
    EXPECT_EQ(CodeOf([&] { store.Materialize(Sha256Hex("nope"), dest.string()); }),
              ErrorCode::kNotFound);
}

}  // namespace
}  // namespace tessera

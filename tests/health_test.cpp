// The coordinator process's other faces: gRPC health checking of the server and of each
// service by name, server reflection (what grpcurl and grpc_cli list), and the dashboard's
// port (--http-listen, --http-port-file) with its refusal to listen off loopback
// unprotected. A real tessera-coordinator on 127.0.0.1.
//
// Debian ships neither the health nor the reflection .proto, so the calls are made with
// gRPC's generic stub and their messages written and read as protobuf wire format.

#include <google/protobuf/unknown_field_set.h>
#include <grpcpp/generic/generic_stub.h>
#include <httplib.h>

#include <future>

#include "farm_harness.h"

namespace tessera::farm_testing {
namespace {

constexpr const char* kHealthCheck = "/grpc.health.v1.Health/Check";
constexpr const char* kReflection =
    "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo";
constexpr int kServing = 1;  // grpc.health.v1.HealthCheckResponse.ServingStatus.SERVING

// A string field of a message, as protobuf's wire format writes it (short values only).
std::string StringField(int number, const std::string& value) {
    EXPECT_LT(value.size(), 128u);
    return std::string(1, char(number << 3 | 2)) + char(value.size()) + value;
}

grpc::ByteBuffer ToBuffer(const std::string& bytes) {
    grpc::Slice slice(bytes);
    return grpc::ByteBuffer(&slice, 1);
}

std::string FromBuffer(const grpc::ByteBuffer& buffer) {
    std::vector<grpc::Slice> slices;
    std::string bytes;
    if (!buffer.Dump(&slices).ok()) return bytes;
    for (const grpc::Slice& s : slices)
        bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
    return bytes;
}

// The fields numbered `number` of a serialized message.
std::vector<const google::protobuf::UnknownField*> Fields(
    const google::protobuf::UnknownFieldSet& set, int number) {
    std::vector<const google::protobuf::UnknownField*> out;
    for (int i = 0; i < set.field_count(); ++i)
        if (set.field(i).number() == number) out.push_back(&set.field(i));
    return out;
}

// grpc.health.v1.Health/Check of `service`: the serving status, or -1 with the call's
// status in *status.
int HealthOf(grpc::GenericStub& stub, const std::string& service, grpc::Status* status) {
    Ctx ctx(30s);
    const grpc::ByteBuffer request = ToBuffer(service.empty() ? "" : StringField(1, service));
    grpc::ByteBuffer response;
    std::promise<grpc::Status> done;
    stub.UnaryCall(&ctx, kHealthCheck, grpc::StubOptions(), &request, &response,
                   [&](grpc::Status s) { done.set_value(s); });
    *status = done.get_future().get();
    if (!status->ok()) return -1;
    google::protobuf::UnknownFieldSet fields;
    if (!fields.ParseFromString(FromBuffer(response))) return -1;
    const auto found = Fields(fields, 1);
    return found.empty() ? 0 : int(found[0]->varint());  // proto3 leaves 0 out
}

// One request on the reflection stream, then its end; the one response.
class ReflectionExchange final
    : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
  public:
    ReflectionExchange(grpc::GenericStub& stub, const std::string& request)
        : request_(ToBuffer(request)) {
        context_.set_deadline(std::chrono::system_clock::now() + 30s);
        context_.set_wait_for_ready(true);
        stub.PrepareBidiStreamingCall(&context_, kReflection, grpc::StubOptions(), this);
        StartWriteLast(&request_, grpc::WriteOptions());
        StartRead(&response_);
        StartCall();
    }
    void OnReadDone(bool ok) override { read_ = ok; }
    void OnDone(const grpc::Status& status) override { done_.set_value(status); }

    // The call's status and the response's bytes ("" if none came).
    grpc::Status Wait(std::string* response) {
        grpc::Status status = done_.get_future().get();
        *response = read_ ? FromBuffer(response_) : "";
        return status;
    }

  private:
    grpc::ClientContext context_;
    grpc::ByteBuffer request_, response_;
    bool read_ = false;
    std::promise<grpc::Status> done_;
};

// ServerReflectionRequest{list_services: ""} -> the names in
// ServerReflectionResponse.list_services_response (6) .service (1) .name (1).
std::vector<std::string> ListServices(grpc::GenericStub& stub) {
    ReflectionExchange exchange(stub, StringField(7, ""));
    std::string bytes;
    grpc::Status status = exchange.Wait(&bytes);
    EXPECT_TRUE(status.ok()) << status.error_message();
    std::vector<std::string> names;
    google::protobuf::UnknownFieldSet response, list;
    if (!response.ParseFromString(bytes)) return names;
    for (const auto* field : Fields(response, 6))
        if (list.ParseFromString(field->length_delimited()))
            for (const auto* service : Fields(list, 1)) {
                google::protobuf::UnknownFieldSet entry;
                if (!entry.ParseFromString(service->length_delimited())) continue;
                for (const auto* name : Fields(entry, 1)) names.push_back(name->length_delimited());
            }
    return names;
}

class CoordinatorProcessTest : public FarmHarness {};

TEST_F(CoordinatorProcessTest, HealthPerServiceReflectionAndTheDashboardPort) {
    const fs::path http_port_file = dir_ / "http.port";
    const int port = StartCoordinator(
        "state", 0, 0, nullptr,
        {"--http-listen", "127.0.0.1:0", "--http-port-file", http_port_file.string()});
    ASSERT_GT(port, 0);
    auto channel = MakeTestChannel(port);
    grpc::GenericStub stub(channel);

    for (const std::string service :
         {"", "tessera.v1.Farm", "tessera.v1.Workers", "tessera.v1.BlobStore"}) {
        grpc::Status status;
        EXPECT_EQ(HealthOf(stub, service, &status), kServing)
            << "'" << service << "': " << status.error_message();
    }
    grpc::Status status;
    HealthOf(stub, "tessera.v1.NoSuchService", &status);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);

    const std::vector<std::string> services = ListServices(stub);
    for (const char* name :
         {"tessera.v1.Farm", "tessera.v1.Workers", "tessera.v1.BlobStore", "grpc.health.v1.Health"})
        EXPECT_NE(std::find(services.begin(), services.end(), name), services.end())
            << name << " is not listed; listed: " << Join(services);

    // The dashboard's port is written before the gRPC one: it serves by now.
    const std::string text = Trim(ReadFile(http_port_file));
    ASSERT_FALSE(text.empty()) << "no " << http_port_file;
    const int http_port = std::stoi(text);
    ASSERT_GT(http_port, 0);
    EXPECT_NE(http_port, port);
    httplib::Client http("127.0.0.1", http_port);
    httplib::Result jobs = http.Get("/api/jobs");
    ASSERT_TRUE(jobs) << httplib::to_string(jobs.error());
    EXPECT_EQ(jobs->status, 200);
    EXPECT_NE(jobs->body.find("\"jobs\":[]"), std::string::npos) << jobs->body;
    httplib::Result metrics = http.Get("/metrics");
    ASSERT_TRUE(metrics);
    EXPECT_EQ(metrics->status, 200);
    EXPECT_NE(metrics->body.find("# TYPE"), std::string::npos);
}

TEST_F(CoordinatorProcessTest, DashboardOffLoopbackNeedsTlsAndTokens) {
    const std::vector<std::string> base = {TESSERA_COORDINATOR, "--state",
                                           (dir_ / "state").string(), "--output",
                                           (dir_ / "out").string()};
    Process& refused =
        Start(Concat(base, {"--listen", "127.0.0.1:0", "--http-listen", "0.0.0.0:0"}), "refused");
    EXPECT_EQ(refused.Wait(120s), 1);
    const std::string log = ReadFile(dir_ / "refused.log");
    EXPECT_NE(log.find("refusing to serve the dashboard on 0.0.0.0:0"), std::string::npos) << log;
    EXPECT_FALSE(fs::exists(dir_ / "state" / "tessera.db")) << "refused before opening the state";

    // --insecure opens the gRPC port, not the dashboard.
    Process& insecure =
        Start(Concat(base, {"--listen", "0.0.0.0:0", "--insecure", "--http-listen", "0.0.0.0:0"}),
              "insecure");
    EXPECT_EQ(insecure.Wait(120s), 1);
    EXPECT_NE(ReadFile(dir_ / "insecure.log").find("refusing to serve the dashboard"),
              std::string::npos);

    // The dashboard's port must be given: HOST alone would be the gRPC port's default.
    Process& no_port =
        Start(Concat(base, {"--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1"}), "no_port");
    EXPECT_EQ(no_port.Wait(120s), 2);
    EXPECT_NE(ReadFile(dir_ / "no_port.log").find("--http-listen"), std::string::npos);
}

}  // namespace
}  // namespace tessera::farm_testing

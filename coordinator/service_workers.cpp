// Workers service adapter: registration, long-poll leases, heartbeats, results.

#include <spdlog/spdlog.h>

#include <atomic>
#include <functional>

#include "grpc_status.h"
#include "services.h"
#include "tessera/v1/tessera.grpc.pb.h"

namespace tessera {
namespace {

void ToProto(const LeasedTask& t, v1::Task* out) {
    out->set_task_id(t.task_id);
    out->set_lease_id(t.lease_id);
    out->set_lease_token(t.lease_token);
    out->set_job_id(t.job_id);
    out->set_frame(t.frame);
    out->set_stage(t.stage);
    out->set_task_index(t.task_index);
    *out->mutable_spec() = *t.spec;
    out->set_attempt(t.attempt);
    for (const TaskInputRef& in : t.inputs) {
        v1::TaskInput* input = out->add_inputs();
        input->set_stage(in.stage);
        input->set_hash(in.hash);
        input->set_size(in.size);
    }
}

// Guarded, except that a lease the caller does not hold is PERMISSION_DENIED (the
// logic layer's error codes have none).
grpc::Status LeaseGuarded(const std::function<void()>& body) {
    std::string denied;
    grpc::Status status = Guarded([&] {
        try {
            body();
        } catch (const LeaseNotHeld& e) {
            denied = e.what();
        }
    });
    if (!denied.empty()) return grpc::Status(grpc::StatusCode::PERMISSION_DENIED, denied);
    return status;
}

// A long poll: parked in the coordinator's dispatcher until a task is leased to it,
// its wait runs out, or the client goes away; no gRPC thread waits meanwhile.
class LeaseReactor final : public grpc::ServerUnaryReactor {
  public:
    LeaseReactor(Coordinator& c, const v1::LeaseTaskRequest& req, v1::LeaseTaskResponse* resp)
        : c_(c), resp_(resp) {
        handle_ = c_.LeaseTask(req.worker_id(), req.wait_ms(),
                               [this](std::optional<LeasedTask> task, std::exception_ptr error) {
                                   if (error) {
                                       Finish(ExceptionStatus(error));
                                       return;
                                   }
                                   if (task) ToProto(*task, resp_->mutable_task());
                                   Finish(grpc::Status::OK);
                               });
    }
    void OnCancel() override {
        if (handle_) c_.CancelLeaseWait(handle_);
    }
    void OnDone() override { delete this; }

  private:
    Coordinator& c_;
    v1::LeaseTaskResponse* resp_;
    uint64_t handle_ = 0;
};

class WorkersService final : public v1::Workers::CallbackService {
  public:
    WorkersService(Coordinator& c, const Authenticator& auth) : c_(c), auth_(auth) {}

    grpc::ServerUnaryReactor* Register(grpc::CallbackServerContext* ctx,
                                       const v1::RegisterRequest* req,
                                       v1::RegisterResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kWorker, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "registration of worker '" + req->name() + "'");
        reactor->Finish(Guarded([&] {
            WorkerRegistration r = c_.Register(req->name(), req->threads());
            resp->set_worker_id(r.worker_id);
            resp->set_heartbeat_interval_ms(r.heartbeat_interval_ms);
            resp->set_lease_duration_ms(r.lease_duration_ms);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* LeaseTask(grpc::CallbackServerContext* ctx,
                                        const v1::LeaseTaskRequest* req,
                                        v1::LeaseTaskResponse* resp) override {
        Caller caller;
        if (grpc::Status s = auth_.Check(*ctx, Role::kWorker, &caller); !s.ok()) {
            grpc::ServerUnaryReactor* refused = ctx->DefaultReactor();
            refused->Finish(s);
            return refused;
        }
        return new LeaseReactor(c_, *req, resp);
    }

    grpc::ServerUnaryReactor* Heartbeat(grpc::CallbackServerContext* ctx,
                                        const v1::HeartbeatRequest* req,
                                        v1::HeartbeatResponse* resp) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kWorker, reactor, &caller)) return reactor;
        // A lease renewal: logged at debug only, it comes every few seconds per task.
        spdlog::debug("heartbeat for task {} by '{}' from {}", req->task_id(), caller.name,
                      caller.peer);
        reactor->Finish(LeaseGuarded([&] {
            HeartbeatReply r =
                c_.Heartbeat(req->worker_id(), req->task_id(), req->lease_id(), req->lease_token(),
                             {req->samples_done(), req->rays_traced()});
            resp->set_lease_valid(r.lease_valid);
            resp->set_cancelled(r.cancelled);
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* CompleteTask(grpc::CallbackServerContext* ctx,
                                           const v1::CompleteTaskRequest* req,
                                           v1::CompleteTaskResponse*) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kWorker, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "result for task " + std::to_string(req->task_id()) + " (lease " +
                                    std::to_string(req->lease_id()) + ")");
        reactor->Finish(LeaseGuarded([&] {
            c_.CompleteTask(req->worker_id(), req->task_id(), req->lease_id(), req->lease_token(),
                            req->result_hash(), req->result());
        }));
        return reactor;
    }

    grpc::ServerUnaryReactor* FailTask(grpc::CallbackServerContext* ctx,
                                       const v1::FailTaskRequest* req,
                                       v1::FailTaskResponse*) override {
        grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
        Caller caller;
        if (!Admit(auth_, ctx, Role::kWorker, reactor, &caller)) return reactor;
        LogMutatingCall(caller, "failure of task " + std::to_string(req->task_id()) + " (lease " +
                                    std::to_string(req->lease_id()) + ")");
        reactor->Finish(LeaseGuarded([&] {
            c_.FailTask(req->worker_id(), req->task_id(), req->lease_id(), req->lease_token(),
                        req->message(), req->log_tail().substr(0, 8192));
        }));
        return reactor;
    }

  private:
    Coordinator& c_;
    const Authenticator& auth_;
};

}  // namespace

std::unique_ptr<grpc::Service> MakeWorkersService(Coordinator& coordinator,
                                                  const Authenticator& auth) {
    return std::make_unique<WorkersService>(coordinator, auth);
}

}  // namespace tessera

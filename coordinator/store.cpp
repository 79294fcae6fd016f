#include "store.h"

#include <algorithm>

#include "tessera/v1/tessera.pb.h"

namespace tessera {

namespace {

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS jobs(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  state INTEGER NOT NULL,
  priority INTEGER NOT NULL,
  spec BLOB NOT NULL,
  frame_start INTEGER NOT NULL,
  frame_end INTEGER NOT NULL,
  first_task_id INTEGER NOT NULL,
  tasks_per_frame INTEGER NOT NULL,
  tasks_total INTEGER NOT NULL,
  tasks_done INTEGER NOT NULL DEFAULT 0,
  leases_granted INTEGER NOT NULL DEFAULT 0,
  error TEXT NOT NULL DEFAULT '',
  submitted_ms INTEGER NOT NULL,
  started_ms INTEGER NOT NULL DEFAULT 0,
  finished_ms INTEGER NOT NULL DEFAULT 0,
  width INTEGER NOT NULL, height INTEGER NOT NULL, spp INTEGER NOT NULL,
  max_depth INTEGER NOT NULL, tile_size INTEGER NOT NULL, seed INTEGER NOT NULL,
  integrator TEXT NOT NULL, sampler TEXT NOT NULL, scene_name TEXT NOT NULL,
  settings TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS frames(
  job_id INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  state INTEGER NOT NULL,
  tasks_total INTEGER NOT NULL,
  tasks_done INTEGER NOT NULL DEFAULT 0,
  first_task_id INTEGER NOT NULL,
  started_ms INTEGER NOT NULL DEFAULT 0,
  exr_path TEXT NOT NULL DEFAULT '',
  PRIMARY KEY(job_id, frame)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS stages(
  job_id INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  stage_index INTEGER NOT NULL,
  name TEXT NOT NULL,
  label TEXT NOT NULL,
  num_tasks INTEGER NOT NULL,
  first_task_id INTEGER NOT NULL,
  tasks_done INTEGER NOT NULL DEFAULT 0,
  produces_artifact INTEGER NOT NULL,
  merged INTEGER NOT NULL DEFAULT 0,
  artifact_hash TEXT NOT NULL DEFAULT '',
  artifact_size INTEGER NOT NULL DEFAULT 0,
  PRIMARY KEY(job_id, frame, stage_index)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS tasks(
  id INTEGER PRIMARY KEY,
  job_id INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  stage TEXT NOT NULL,
  stage_index INTEGER NOT NULL,
  task_index INTEGER NOT NULL,
  priority INTEGER NOT NULL,
  state INTEGER NOT NULL DEFAULT 0,
  attempts INTEGER NOT NULL DEFAULT 0,
  failures INTEGER NOT NULL DEFAULT 0,
  lease_id INTEGER NOT NULL DEFAULT 0,
  worker_id INTEGER NOT NULL DEFAULT 0,
  result_hash TEXT NOT NULL DEFAULT '',
  completions INTEGER NOT NULL DEFAULT 0,
  lease_token TEXT NOT NULL DEFAULT '',
  failed_worker_id INTEGER NOT NULL DEFAULT 0);
CREATE INDEX IF NOT EXISTS tasks_pending ON tasks(priority DESC, id) WHERE state = 0;
CREATE INDEX IF NOT EXISTS tasks_leased ON tasks(id) WHERE state = 1;
CREATE TABLE IF NOT EXISTS failures(
  id INTEGER PRIMARY KEY,
  job_id INTEGER NOT NULL,
  frame INTEGER NOT NULL,
  task_index INTEGER NOT NULL,
  worker TEXT NOT NULL,
  message TEXT NOT NULL,
  attempt INTEGER NOT NULL,
  at_ms INTEGER NOT NULL,
  stage TEXT NOT NULL DEFAULT '',
  log_tail TEXT NOT NULL DEFAULT '',
  task INTEGER NOT NULL DEFAULT -1);
CREATE INDEX IF NOT EXISTS failures_by_job ON failures(job_id, id);
CREATE TABLE IF NOT EXISTS workers(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  name TEXT NOT NULL,
  threads INTEGER NOT NULL,
  registered_ms INTEGER NOT NULL,
  disabled INTEGER NOT NULL DEFAULT 0);
CREATE TABLE IF NOT EXISTS job_log(
  id INTEGER PRIMARY KEY,
  job_id INTEGER NOT NULL,
  at_ms INTEGER NOT NULL,
  kind TEXT NOT NULL,
  frame INTEGER NOT NULL,
  stage TEXT NOT NULL,
  task_index INTEGER NOT NULL,
  task INTEGER NOT NULL,
  worker TEXT NOT NULL,
  attempt INTEGER NOT NULL,
  message TEXT NOT NULL,
  log_tail TEXT NOT NULL,
  leased_ms INTEGER NOT NULL);
CREATE INDEX IF NOT EXISTS job_log_by_job ON job_log(job_id, id);
)sql";

constexpr const char* kJobColumns =
    "id, name, state, priority, frame_start, frame_end, first_task_id, tasks_per_frame, "
    "tasks_total, tasks_done, leases_granted, error, submitted_ms, started_ms, finished_ms, "
    "width, height, spp, max_depth, tile_size, seed, integrator, sampler, scene_name, settings";
constexpr const char* kTaskColumns =
    "id, job_id, frame, stage, task_index, state, attempts, failures, lease_id, worker_id, "
    "result_hash, completions, stage_index, lease_token, failed_worker_id";
constexpr const char* kFrameColumns =
    "frame, state, tasks_total, tasks_done, first_task_id, started_ms, exr_path";
constexpr const char* kStageColumns =
    "frame, stage_index, name, label, num_tasks, tasks_done, first_task_id, produces_artifact, "
    "merged, artifact_hash, artifact_size";

std::string Sql(const char* head, const char* columns, const char* tail) {
    return std::string(head) + columns + tail;
}

// Schema 3 added the tasks' lease tokens and the worker each last failed on; schema 4
// the failures' log tails and task numbers, the workers' disabled flag (and the job log,
// a new table).
constexpr int kOldestMigratableVersion = 2;
constexpr const char* kMigrateFrom2 = R"sql(
ALTER TABLE tasks ADD COLUMN lease_token TEXT NOT NULL DEFAULT '';
ALTER TABLE tasks ADD COLUMN failed_worker_id INTEGER NOT NULL DEFAULT 0;
)sql";
constexpr const char* kMigrateFrom3 = R"sql(
ALTER TABLE failures ADD COLUMN log_tail TEXT NOT NULL DEFAULT '';
ALTER TABLE failures ADD COLUMN task INTEGER NOT NULL DEFAULT -1;
ALTER TABLE workers ADD COLUMN disabled INTEGER NOT NULL DEFAULT 0;
)sql";

// A database of another layout is refused rather than misread: its jobs could not be
// planned (before schema 2, a job's settings were not stored in full). Returns the
// version found (0 for a new database).
int64_t CheckSchemaVersion(SqliteDb& db, const std::string& path) {
    SqliteStatement version = db.Prepare("PRAGMA user_version");
    version.Step();
    const int64_t v = version.Int(0);
    version.Reset();
    SqliteStatement tables =
        db.Prepare("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'jobs'");
    tables.Step();
    const bool has_jobs = tables.Int(0) > 0;
    tables.Reset();
    if ((v >= kOldestMigratableVersion && v <= Store::kSchemaVersion) || (v == 0 && !has_jobs))
        return v;
    throw std::runtime_error(
        path + " holds coordinator state of schema version " + std::to_string(v) +
        ", written by another version of the coordinator; this one reads version " +
        std::to_string(Store::kSchemaVersion) +
        " only. Start the coordinator with a fresh --state directory (move this one aside).");
}

}  // namespace

int NewJob::TasksPerFrame() const {
    int n = 0;
    for (const NewStage& s : stages) n += s.num_tasks;
    return n;
}

std::vector<int> NewJob::FrameNumbers() const {
    if (!frames.empty()) return frames;
    std::vector<int> numbers;
    for (int f = frame_start; f <= frame_end; ++f) numbers.push_back(f);
    return numbers;
}

int NewJob::NumFrames() const {
    return frames.empty() ? frame_end - frame_start + 1 : static_cast<int>(frames.size());
}

Store::Store(const std::string& path) : path_(path), db_(path) {
    db_.Exec("PRAGMA journal_mode=WAL");
    db_.Exec("PRAGMA synchronous=NORMAL");
    // Checkpoint() normally keeps the WAL short; this is only the fallback.
    db_.Exec("PRAGMA wal_autocheckpoint=20000");
    db_.Exec("PRAGMA foreign_keys=OFF");
    if (const int64_t version = CheckSchemaVersion(db_, path);
        version != 0 && version < kSchemaVersion) {
        SqliteTransaction txn(db_);
        // Leases outstanding across the upgrade from 2 keep an empty token (see Scheduler).
        if (version <= 2) db_.Exec(kMigrateFrom2);
        if (version <= 3) db_.Exec(kMigrateFrom3);
        txn.Commit();
    }
    db_.Exec(kSchema);
    db_.Exec("PRAGMA user_version = " + std::to_string(kSchemaVersion));

    get_meta_ = db_.Prepare("SELECT value FROM meta WHERE key = ?1");
    set_meta_ = db_.Prepare(
        "INSERT INTO meta(key, value) VALUES(?1, ?2) "
        "ON CONFLICT(key) DO UPDATE SET value = excluded.value");

    insert_job_ = db_.Prepare(
        "INSERT INTO jobs(name, state, priority, spec, frame_start, frame_end, first_task_id, "
        "tasks_per_frame, tasks_total, submitted_ms, width, height, spp, max_depth, tile_size, "
        "seed, integrator, sampler, scene_name, settings) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, "
        "?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20)");
    insert_frame_ = db_.Prepare(
        "INSERT INTO frames(job_id, frame, state, tasks_total, first_task_id) "
        "VALUES(?1, ?2, ?3, ?4, ?5)");
    insert_stage_ = db_.Prepare(
        "INSERT INTO stages(job_id, frame, stage_index, name, label, num_tasks, first_task_id, "
        "produces_artifact) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    insert_task_ = db_.Prepare(
        "INSERT INTO tasks(id, job_id, frame, stage, stage_index, task_index, priority, state) "
        "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    max_task_id_ = db_.Prepare("SELECT COALESCE(MAX(id), 0) FROM tasks");

    get_job_ = db_.Prepare(Sql("SELECT ", kJobColumns, " FROM jobs WHERE id = ?1"));
    get_job_spec_ = db_.Prepare("SELECT spec FROM jobs WHERE id = ?1");
    job_ids_ = db_.Prepare("SELECT id FROM jobs ORDER BY id");
    set_job_state_ =
        db_.Prepare("UPDATE jobs SET state = ?2, error = ?3, finished_ms = ?4 WHERE id = ?1");
    count_lease_ = db_.Prepare(
        "UPDATE jobs SET leases_granted = leases_granted + 1, "
        "state = CASE WHEN state = ?3 THEN ?4 ELSE state END, "
        "started_ms = CASE WHEN started_ms = 0 THEN ?2 ELSE started_ms END WHERE id = ?1");
    count_task_done_ = db_.Prepare("UPDATE jobs SET tasks_done = tasks_done + 1 WHERE id = ?1");
    job_state_ = db_.Prepare("SELECT state FROM jobs WHERE id = ?1");
    uncount_lease_ =
        db_.Prepare("UPDATE jobs SET leases_granted = leases_granted - 1 WHERE id = ?1");

    get_frames_ =
        db_.Prepare(Sql("SELECT ", kFrameColumns, " FROM frames WHERE job_id = ?1 ORDER BY frame"));
    get_frame_ =
        db_.Prepare(Sql("SELECT ", kFrameColumns, " FROM frames WHERE job_id = ?1 AND frame = ?2"));
    frame_rendering_ = db_.Prepare(
        "UPDATE frames SET state = ?4, started_ms = ?3 "
        "WHERE job_id = ?1 AND frame = ?2 AND state = ?5");
    frame_task_done_ = db_.Prepare(
        "UPDATE frames SET tasks_done = tasks_done + 1 WHERE job_id = ?1 AND frame = ?2 "
        "RETURNING tasks_done");
    frame_done_ =
        db_.Prepare("UPDATE frames SET state = ?3, exr_path = ?4 WHERE job_id = ?1 AND frame = ?2");
    fail_open_frames_ =
        db_.Prepare("UPDATE frames SET state = ?2 WHERE job_id = ?1 AND state <> ?3");
    frames_not_done_ = db_.Prepare("SELECT COUNT(*) FROM frames WHERE job_id = ?1 AND state <> ?2");
    frames_awaiting_ = db_.Prepare(
        "SELECT f.job_id, f.frame FROM frames f JOIN jobs j ON j.id = f.job_id "
        "WHERE j.state = ?1 AND f.state <> ?2 AND f.tasks_done = f.tasks_total "
        "ORDER BY f.job_id, f.frame");

    get_stages_ = db_.Prepare(Sql("SELECT ", kStageColumns,
                                  " FROM stages WHERE job_id = ?1 ORDER BY frame, stage_index"));
    get_frame_stages_ = db_.Prepare(Sql("SELECT ", kStageColumns,
                                        " FROM stages WHERE job_id = ?1 AND frame = ?2 "
                                        "ORDER BY stage_index"));
    get_stage_ = db_.Prepare(Sql("SELECT ", kStageColumns,
                                 " FROM stages WHERE job_id = ?1 AND frame = ?2 AND "
                                 "stage_index = ?3"));
    stage_task_done_ = db_.Prepare(
        "UPDATE stages SET tasks_done = tasks_done + 1 "
        "WHERE job_id = ?1 AND frame = ?2 AND stage_index = ?3 RETURNING tasks_done");
    stage_merged_ = db_.Prepare(
        "UPDATE stages SET merged = 1, artifact_hash = ?4, artifact_size = ?5 "
        "WHERE job_id = ?1 AND frame = ?2 AND stage_index = ?3 AND merged = 0");
    release_tasks_ =
        db_.Prepare("UPDATE tasks SET state = 0 WHERE id BETWEEN ?1 AND ?2 AND state = 4");
    stages_awaiting_ = db_.Prepare(
        "SELECT s.job_id, s.frame, s.stage_index FROM stages s JOIN jobs j ON j.id = s.job_id "
        "WHERE j.state = ?1 AND s.produces_artifact = 1 AND s.merged = 0 AND "
        "s.tasks_done = s.num_tasks ORDER BY s.job_id, s.frame, s.stage_index");

    next_pending_ = db_.Prepare(Sql("SELECT ", kTaskColumns,
                                    " FROM tasks WHERE state = 0 ORDER BY priority DESC, id "
                                    "LIMIT 1"));
    // Walks the pending index past the few tasks that last failed on the worker.
    next_pending_avoiding_ = db_.Prepare(Sql("SELECT ", kTaskColumns,
                                             " FROM tasks WHERE state = 0 AND failed_worker_id "
                                             "<> ?1 ORDER BY priority DESC, id LIMIT 1"));
    get_task_ = db_.Prepare(Sql("SELECT ", kTaskColumns, " FROM tasks WHERE id = ?1"));
    lease_task_ = db_.Prepare(
        "UPDATE tasks SET state = 1, lease_id = ?2, worker_id = ?3, lease_token = ?4, "
        "attempts = attempts + 1 WHERE id = ?1 AND state = 0");
    complete_task_ = db_.Prepare(
        "UPDATE tasks SET state = 2, result_hash = ?3, completions = completions + 1 "
        "WHERE id = ?1 AND state = 1 AND lease_id = ?2");
    requeue_task_ = db_.Prepare(
        "UPDATE tasks SET state = 0, failures = failures + ?3, "
        "failed_worker_id = CASE WHEN ?3 > 0 THEN worker_id ELSE failed_worker_id END "
        "WHERE id = ?1 AND state = 1 AND lease_id = ?2");
    release_task_ = db_.Prepare(
        "UPDATE tasks SET state = 0, attempts = attempts - 1 "
        "WHERE id = ?1 AND state = 1 AND lease_id = ?2");
    requeue_done_ = db_.Prepare(
        "UPDATE tasks SET state = 0, result_hash = '' WHERE id = ?1 AND state = 2 AND "
        "completions = ?2");
    uncount_stage_done_ = db_.Prepare(
        "UPDATE stages SET tasks_done = tasks_done - ?4 "
        "WHERE job_id = ?1 AND frame = ?2 AND stage_index = ?3");
    uncount_frame_done_ = db_.Prepare(
        "UPDATE frames SET tasks_done = tasks_done - ?3 WHERE job_id = ?1 AND frame = ?2");
    uncount_job_done_ = db_.Prepare("UPDATE jobs SET tasks_done = tasks_done - ?2 WHERE id = ?1");
    drop_tasks_ =
        db_.Prepare("UPDATE tasks SET state = 3 WHERE id BETWEEN ?1 AND ?2 AND state IN (0, 1, 4)");
    leased_tasks_ = db_.Prepare(Sql("SELECT ", kTaskColumns, " FROM tasks WHERE state = 1"));
    stage_results_ = db_.Prepare(
        "SELECT task_index, result_hash, completions FROM tasks WHERE id BETWEEN ?1 AND ?2 "
        "ORDER BY id");

    insert_failure_ = db_.Prepare(
        "INSERT INTO failures(job_id, frame, task_index, worker, message, attempt, at_ms, "
        "stage, log_tail, task) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)");
    recent_failures_ = db_.Prepare(
        "SELECT frame, task_index, attempt, worker, message, stage, log_tail, task "
        "FROM failures WHERE job_id = ?1 ORDER BY id DESC LIMIT ?2");
    insert_worker_ =
        db_.Prepare("INSERT INTO workers(name, threads, registered_ms) VALUES(?1, ?2, ?3)");
    update_worker_ =
        db_.Prepare("UPDATE workers SET threads = ?2, registered_ms = ?3 WHERE id = ?1");
    workers_ = db_.Prepare("SELECT id, name, threads, disabled FROM workers ORDER BY id");
    set_worker_disabled_ = db_.Prepare("UPDATE workers SET disabled = ?2 WHERE id = ?1");
    insert_log_ = db_.Prepare(
        "INSERT INTO job_log(job_id, at_ms, kind, frame, stage, task_index, task, worker, "
        "attempt, message, log_tail, leased_ms) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, "
        "?11, ?12)");
}

void Store::Checkpoint() {
    if (!checkpoint_db_) {
        checkpoint_db_ = std::make_unique<SqliteDb>(path_);
        checkpoint_db_->Exec("PRAGMA synchronous=NORMAL");
    }
    checkpoint_db_->Exec("PRAGMA wal_checkpoint(PASSIVE)");
}

int64_t Store::GetMeta(const std::string& key, int64_t fallback) {
    get_meta_.Bind(key);
    int64_t value = get_meta_.Step() ? get_meta_.Int(0) : fallback;
    get_meta_.Reset();
    return value;
}

void Store::SetMeta(const std::string& key, int64_t value) { set_meta_.Bind(key, value).Run(); }

int64_t Store::UnfinishedTasks() {
    SqliteStatement sum = db_.Prepare(
        "SELECT COALESCE(SUM(tasks_total - tasks_done), 0) FROM jobs WHERE state IN (?1, ?2)");
    sum.Bind(int(v1::JOB_STATE_QUEUED), int(v1::JOB_STATE_RUNNING));
    const int64_t n = sum.Step() ? sum.Int(0) : 0;
    sum.Reset();
    return n;
}

int64_t Store::InsertJob(const NewJob& job, int64_t now_ms) {
    max_task_id_.Bind();
    max_task_id_.Step();
    const int64_t first_task = max_task_id_.Int(0) + 1;
    max_task_id_.Reset();
    const int frames = job.NumFrames();
    const int tasks_per_frame = job.TasksPerFrame();
    const JobSettings& s = job.settings;
    insert_job_
        .Bind(job.name, int(v1::JOB_STATE_QUEUED), job.priority, SqliteBlobArg{job.spec},
              job.frame_start, job.frame_end, first_task, tasks_per_frame,
              int64_t(frames) * tasks_per_frame, now_ms, s.width, s.height, s.spp, s.max_depth,
              s.tile_size, s.seed, s.integrator, s.sampler, s.scene_name, job.render_settings)
        .Run();
    const int64_t job_id = db_.LastInsertRowid();
    int64_t task_id = first_task;
    for (int f : job.FrameNumbers()) {
        insert_frame_.Bind(job_id, f, int(v1::FRAME_STATE_PENDING), tasks_per_frame, task_id).Run();
        for (size_t si = 0; si < job.stages.size(); ++si) {
            const NewStage& stage = job.stages[si];
            insert_stage_
                .Bind(job_id, f, int(si), stage.name, stage.label, stage.num_tasks, task_id,
                      stage.produces_artifact ? 1 : 0)
                .Run();
            const int state = int(stage.waiting ? TaskState::kWaiting : TaskState::kPending);
            for (int i = 0; i < stage.num_tasks; ++i)
                insert_task_.Bind(task_id++, job_id, f, stage.name, int(si), i, job.priority, state)
                    .Run();
        }
    }
    return job_id;
}

std::optional<JobRow> Store::GetJob(int64_t job_id) {
    get_job_.Bind(job_id);
    if (!get_job_.Step()) return std::nullopt;
    const SqliteStatement& s = get_job_;
    JobRow j;
    j.id = s.Int(0);
    j.name = s.Text(1);
    j.state = int(s.Int(2));
    j.priority = int(s.Int(3));
    j.frame_start = int(s.Int(4));
    j.frame_end = int(s.Int(5));
    j.first_task_id = s.Int(6);
    j.tasks_per_frame = int(s.Int(7));
    j.tasks_total = int(s.Int(8));
    j.tasks_done = int(s.Int(9));
    j.leases_granted = s.Int(10);
    j.error = s.Text(11);
    j.submitted_ms = s.Int(12);
    j.started_ms = s.Int(13);
    j.finished_ms = s.Int(14);
    j.settings.width = int(s.Int(15));
    j.settings.height = int(s.Int(16));
    j.settings.spp = int(s.Int(17));
    j.settings.max_depth = int(s.Int(18));
    j.settings.tile_size = int(s.Int(19));
    j.settings.seed = static_cast<uint64_t>(s.Int(20));
    j.settings.integrator = s.Text(21);
    j.settings.sampler = s.Text(22);
    j.settings.scene_name = s.Text(23);
    j.render_settings = s.Text(24);
    get_job_.Reset();
    return j;
}

std::string Store::GetJobSpec(int64_t job_id) {
    get_job_spec_.Bind(job_id);
    std::string spec = get_job_spec_.Step() ? get_job_spec_.Blob(0) : std::string();
    get_job_spec_.Reset();
    return spec;
}

std::vector<std::string> Store::LiveBlobHashes() {
    std::vector<std::string> live;
    SqliteStatement specs = db_.Prepare("SELECT spec FROM jobs");
    while (specs.Step()) {
        v1::JobSpec spec;
        if (!spec.ParseFromString(specs.Blob(0)))
            throw std::runtime_error("a stored job spec is corrupt: no blob can be collected");
        for (const v1::BundleFile& f : spec.files()) live.push_back(f.hash());
        for (const v1::PrecomputedTable& t : spec.tables()) live.push_back(t.hash());
    }
    SqliteStatement results = db_.Prepare(
        "SELECT t.result_hash FROM tasks t JOIN frames f ON f.job_id = t.job_id AND "
        "f.frame = t.frame WHERE f.state <> ?1 AND t.result_hash <> ''");
    results.Bind(int(v1::FRAME_STATE_DONE));
    while (results.Step()) live.push_back(results.Text(0));
    SqliteStatement artifacts = db_.Prepare(
        "SELECT s.artifact_hash FROM stages s JOIN frames f ON f.job_id = s.job_id AND "
        "f.frame = s.frame WHERE f.state <> ?1 AND s.artifact_hash <> ''");
    artifacts.Bind(int(v1::FRAME_STATE_DONE));
    while (artifacts.Step()) live.push_back(artifacts.Text(0));
    return live;
}

std::vector<int64_t> Store::JobIds() {
    std::vector<int64_t> ids;
    job_ids_.Bind();
    while (job_ids_.Step()) ids.push_back(job_ids_.Int(0));
    return ids;
}

void Store::SetJobState(int64_t job_id, int state, const std::string& error, int64_t finished_ms) {
    set_job_state_.Bind(job_id, state, error, finished_ms).Run();
}

void Store::CountLease(int64_t job_id, int64_t now_ms) {
    count_lease_.Bind(job_id, now_ms, int(v1::JOB_STATE_QUEUED), int(v1::JOB_STATE_RUNNING)).Run();
}

void Store::CountTaskDone(int64_t job_id) { count_task_done_.Bind(job_id).Run(); }

std::optional<int> Store::JobState(int64_t job_id) {
    job_state_.Bind(job_id);
    if (!job_state_.Step()) return std::nullopt;
    int state = int(job_state_.Int(0));
    job_state_.Reset();
    return state;
}

FrameRow Store::ReadFrame(const SqliteStatement& s) const {
    FrameRow f;
    f.frame = int(s.Int(0));
    f.state = int(s.Int(1));
    f.tasks_total = int(s.Int(2));
    f.tasks_done = int(s.Int(3));
    f.first_task_id = s.Int(4);
    f.started_ms = s.Int(5);
    f.exr_path = s.Text(6);
    return f;
}

std::vector<FrameRow> Store::GetFrames(int64_t job_id) {
    std::vector<FrameRow> frames;
    get_frames_.Bind(job_id);
    while (get_frames_.Step()) frames.push_back(ReadFrame(get_frames_));
    return frames;
}

std::optional<FrameRow> Store::GetFrame(int64_t job_id, int frame) {
    get_frame_.Bind(job_id, frame);
    if (!get_frame_.Step()) return std::nullopt;
    FrameRow f = ReadFrame(get_frame_);
    get_frame_.Reset();
    return f;
}

void Store::MarkFrameRendering(int64_t job_id, int frame, int64_t now_ms) {
    frame_rendering_
        .Bind(job_id, frame, now_ms, int(v1::FRAME_STATE_RENDERING), int(v1::FRAME_STATE_PENDING))
        .Run();
}

int Store::CountFrameTaskDone(int64_t job_id, int frame) {
    frame_task_done_.Bind(job_id, frame);
    int done = frame_task_done_.Step() ? int(frame_task_done_.Int(0)) : 0;
    frame_task_done_.Reset();
    return done;
}

void Store::SetFrameDone(int64_t job_id, int frame, const std::string& exr_path) {
    frame_done_.Bind(job_id, frame, int(v1::FRAME_STATE_DONE), exr_path).Run();
}

void Store::EndOpenFrames(int64_t job_id, int state) {
    fail_open_frames_.Bind(job_id, state, int(v1::FRAME_STATE_DONE)).Run();
}

int Store::CountFramesNotDone(int64_t job_id) {
    frames_not_done_.Bind(job_id, int(v1::FRAME_STATE_DONE));
    frames_not_done_.Step();
    int n = int(frames_not_done_.Int(0));
    frames_not_done_.Reset();
    return n;
}

std::vector<std::pair<int64_t, int>> Store::FramesAwaitingAssembly() {
    std::vector<std::pair<int64_t, int>> out;
    frames_awaiting_.Bind(int(v1::JOB_STATE_RUNNING), int(v1::FRAME_STATE_DONE));
    while (frames_awaiting_.Step())
        out.emplace_back(frames_awaiting_.Int(0), int(frames_awaiting_.Int(1)));
    return out;
}

StageRow Store::ReadStage(const SqliteStatement& s) const {
    StageRow r;
    r.frame = int(s.Int(0));
    r.index = int(s.Int(1));
    r.name = s.Text(2);
    r.label = s.Text(3);
    r.num_tasks = int(s.Int(4));
    r.tasks_done = int(s.Int(5));
    r.first_task_id = s.Int(6);
    r.produces_artifact = s.Int(7) != 0;
    r.merged = s.Int(8) != 0;
    r.artifact_hash = s.Text(9);
    r.artifact_size = static_cast<uint64_t>(s.Int(10));
    return r;
}

std::vector<StageRow> Store::GetStages(int64_t job_id) {
    std::vector<StageRow> out;
    get_stages_.Bind(job_id);
    while (get_stages_.Step()) out.push_back(ReadStage(get_stages_));
    return out;
}

std::vector<StageRow> Store::GetFrameStages(int64_t job_id, int frame) {
    std::vector<StageRow> out;
    get_frame_stages_.Bind(job_id, frame);
    while (get_frame_stages_.Step()) out.push_back(ReadStage(get_frame_stages_));
    return out;
}

std::optional<StageRow> Store::GetStage(int64_t job_id, int frame, int stage) {
    get_stage_.Bind(job_id, frame, stage);
    if (!get_stage_.Step()) return std::nullopt;
    StageRow r = ReadStage(get_stage_);
    get_stage_.Reset();
    return r;
}

int Store::CountStageTaskDone(int64_t job_id, int frame, int stage) {
    stage_task_done_.Bind(job_id, frame, stage);
    int done = stage_task_done_.Step() ? int(stage_task_done_.Int(0)) : 0;
    stage_task_done_.Reset();
    return done;
}

bool Store::SetStageMerged(int64_t job_id, int frame, int stage, const std::string& hash,
                           uint64_t size) {
    stage_merged_.Bind(job_id, frame, stage, hash, size).Run();
    return db_.Changes() == 1;
}

int Store::ReleaseTasks(int64_t first_task_id, int64_t last_task_id) {
    release_tasks_.Bind(first_task_id, last_task_id).Run();
    return int(db_.Changes());
}

std::vector<std::tuple<int64_t, int, int>> Store::StagesAwaitingMerge() {
    std::vector<std::tuple<int64_t, int, int>> out;
    stages_awaiting_.Bind(int(v1::JOB_STATE_RUNNING));
    while (stages_awaiting_.Step())
        out.emplace_back(stages_awaiting_.Int(0), int(stages_awaiting_.Int(1)),
                         int(stages_awaiting_.Int(2)));
    return out;
}

TaskRow Store::ReadTask(const SqliteStatement& s) const {
    TaskRow t;
    t.id = s.Int(0);
    t.job_id = s.Int(1);
    t.frame = int(s.Int(2));
    t.stage = s.Text(3);
    t.task_index = int(s.Int(4));
    t.state = static_cast<TaskState>(s.Int(5));
    t.attempts = int(s.Int(6));
    t.failures = int(s.Int(7));
    t.lease_id = s.Int(8);
    t.worker_id = s.Int(9);
    t.result_hash = s.Text(10);
    t.completions = int(s.Int(11));
    t.stage_index = int(s.Int(12));
    t.lease_token = s.Text(13);
    t.failed_worker_id = s.Int(14);
    return t;
}

std::optional<TaskRow> Store::NextPendingTask() {
    next_pending_.Bind();
    if (!next_pending_.Step()) return std::nullopt;
    TaskRow t = ReadTask(next_pending_);
    next_pending_.Reset();
    return t;
}

std::optional<TaskRow> Store::NextPendingTaskAvoiding(int64_t worker_id) {
    next_pending_avoiding_.Bind(worker_id);
    if (!next_pending_avoiding_.Step()) return std::nullopt;
    TaskRow t = ReadTask(next_pending_avoiding_);
    next_pending_avoiding_.Reset();
    return t;
}

std::optional<TaskRow> Store::GetTask(int64_t task_id) {
    get_task_.Bind(task_id);
    if (!get_task_.Step()) return std::nullopt;
    TaskRow t = ReadTask(get_task_);
    get_task_.Reset();
    return t;
}

void Store::LeaseTask(int64_t task_id, int64_t lease_id, int64_t worker_id,
                      const std::string& lease_token) {
    lease_task_.Bind(task_id, lease_id, worker_id, lease_token).Run();
}

bool Store::CompleteTask(int64_t task_id, int64_t lease_id, const std::string& result_hash) {
    complete_task_.Bind(task_id, lease_id, result_hash).Run();
    return db_.Changes() == 1;
}

bool Store::RequeueTask(int64_t task_id, int64_t lease_id, bool count_failure) {
    requeue_task_.Bind(task_id, lease_id, count_failure ? 1 : 0).Run();
    return db_.Changes() == 1;
}

bool Store::ReleaseTask(int64_t task_id, int64_t lease_id, int64_t job_id) {
    release_task_.Bind(task_id, lease_id).Run();
    if (db_.Changes() != 1) return false;
    uncount_lease_.Bind(job_id).Run();
    return true;
}

bool Store::RequeueDoneTask(int64_t task_id, int completions) {
    requeue_done_.Bind(task_id, completions).Run();
    return db_.Changes() == 1;
}

void Store::UncountTasksDone(int64_t job_id, int frame, int stage, int n) {
    uncount_stage_done_.Bind(job_id, frame, stage, n).Run();
    uncount_frame_done_.Bind(job_id, frame, n).Run();
    uncount_job_done_.Bind(job_id, n).Run();
}

void Store::DropTasks(int64_t first_task_id, int64_t last_task_id) {
    drop_tasks_.Bind(first_task_id, last_task_id).Run();
}

std::vector<TaskRow> Store::LeasedTasks() {
    std::vector<TaskRow> tasks;
    leased_tasks_.Bind();
    while (leased_tasks_.Step()) tasks.push_back(ReadTask(leased_tasks_));
    return tasks;
}

std::vector<std::pair<int, std::string>> Store::StageResults(const StageRow& stage,
                                                             std::vector<int>* completions) {
    std::vector<std::pair<int, std::string>> out;
    out.reserve(stage.num_tasks);
    stage_results_.Bind(stage.first_task_id, stage.first_task_id + stage.num_tasks - 1);
    while (stage_results_.Step()) {
        out.emplace_back(int(stage_results_.Int(0)), stage_results_.Text(1));
        if (completions) completions->push_back(int(stage_results_.Int(2)));
    }
    return out;
}

void Store::InsertFailure(int64_t job_id, const FailureRow& f, int64_t now_ms) {
    insert_failure_
        .Bind(job_id, f.frame, f.task_index, f.worker, f.message, f.attempt, now_ms, f.stage,
              f.log_tail, f.task)
        .Run();
}

std::vector<FailureRow> Store::RecentFailures(int64_t job_id, int limit) {
    std::vector<FailureRow> out;
    recent_failures_.Bind(job_id, limit);
    while (recent_failures_.Step()) {
        FailureRow f;
        f.frame = int(recent_failures_.Int(0));
        f.task_index = int(recent_failures_.Int(1));
        f.attempt = int(recent_failures_.Int(2));
        f.worker = recent_failures_.Text(3);
        f.message = recent_failures_.Text(4);
        f.stage = recent_failures_.Text(5);
        f.log_tail = recent_failures_.Text(6);
        f.task = recent_failures_.Int(7);
        out.push_back(std::move(f));
    }
    return out;
}

int64_t Store::InsertWorker(const std::string& name, int threads, int64_t now_ms) {
    insert_worker_.Bind(name, threads, now_ms).Run();
    return db_.LastInsertRowid();
}

void Store::UpdateWorker(int64_t id, int threads, int64_t now_ms) {
    update_worker_.Bind(id, threads, now_ms).Run();
}

std::vector<WorkerRow> Store::Workers() {
    std::vector<WorkerRow> out;
    workers_.Bind();
    while (workers_.Step())
        out.push_back(
            {workers_.Int(0), workers_.Text(1), int(workers_.Int(2)), workers_.Int(3) != 0});
    return out;
}

void Store::SetWorkerDisabled(int64_t id, bool disabled) {
    set_worker_disabled_.Bind(id, disabled ? 1 : 0).Run();
}

void Store::InsertLog(const LogRow& e) {
    insert_log_
        .Bind(e.job_id, e.at_ms, e.kind, e.frame, e.stage, e.task_index, e.task, e.worker,
              e.attempt, e.message, e.log_tail, e.leased_ms)
        .Run();
}

std::vector<LogRow> Store::JobLog(int64_t job_id, std::optional<int64_t> task, int limit) {
    // The last `limit` entries, read newest first and returned oldest first.
    SqliteStatement q = db_.Prepare(
        task ? "SELECT job_id, at_ms, kind, frame, stage, task_index, task, worker, attempt, "
               "message, log_tail, leased_ms FROM job_log WHERE job_id = ?1 AND task = ?2 "
               "ORDER BY id DESC LIMIT ?3"
             : "SELECT job_id, at_ms, kind, frame, stage, task_index, task, worker, attempt, "
               "message, log_tail, leased_ms FROM job_log WHERE job_id = ?1 ORDER BY id DESC "
               "LIMIT ?3");
    if (task)
        q.Bind(job_id, *task, limit);
    else
        q.Bind(job_id, int64_t(-1), limit);
    std::vector<LogRow> out;
    while (q.Step()) {
        LogRow e;
        e.job_id = q.Int(0);
        e.at_ms = q.Int(1);
        e.kind = q.Text(2);
        e.frame = int(q.Int(3));
        e.stage = q.Text(4);
        e.task_index = int(q.Int(5));
        e.task = q.Int(6);
        e.worker = q.Text(7);
        e.attempt = int(q.Int(8));
        e.message = q.Text(9);
        e.log_tail = q.Text(10);
        e.leased_ms = q.Int(11);
        out.push_back(std::move(e));
    }
    std::reverse(out.begin(), out.end());
    return out;
}

void Store::SetJobPriority(int64_t job_id, int priority) {
    const std::optional<JobRow> job = GetJob(job_id);
    if (!job) return;
    db_.Prepare("UPDATE jobs SET priority = ?2 WHERE id = ?1").Bind(job_id, priority).Run();
    // The pending queue is ordered by the tasks' own copy of the priority.
    db_.Prepare("UPDATE tasks SET priority = ?3 WHERE id BETWEEN ?1 AND ?2")
        .Bind(job->first_task_id, job->first_task_id + job->tasks_total - 1, priority)
        .Run();
}

void Store::ReopenJob(int64_t job_id) {
    // A job that ran before runs on (its stages may need merging, frames assembling).
    db_.Prepare(
           "UPDATE jobs SET state = CASE WHEN started_ms > 0 THEN ?3 ELSE ?2 END, error = '', "
           "finished_ms = 0 WHERE id = ?1")
        .Bind(job_id, int(v1::JOB_STATE_QUEUED), int(v1::JOB_STATE_RUNNING))
        .Run();
    db_.Prepare("UPDATE frames SET state = ?2, started_ms = 0 WHERE job_id = ?1 AND state <> ?3")
        .Bind(job_id, int(v1::FRAME_STATE_PENDING), int(v1::FRAME_STATE_DONE))
        .Run();
}

int Store::ReopenTasks(int64_t first_task_id, int64_t last_task_id, TaskState state) {
    db_.Prepare(
           "UPDATE tasks SET state = ?3, failures = 0, failed_worker_id = 0, lease_id = 0, "
           "lease_token = '' WHERE id BETWEEN ?1 AND ?2 AND state = 3")
        .Bind(first_task_id, last_task_id, int(state))
        .Run();
    return int(db_.Changes());
}

void Store::DeleteJob(int64_t job_id, std::vector<std::string>* inputs,
                      std::vector<std::string>* outputs) {
    const std::optional<JobRow> job = GetJob(job_id);
    if (!job) return;
    v1::JobSpec spec;
    if (spec.ParseFromString(GetJobSpec(job_id))) {
        for (const v1::BundleFile& f : spec.files()) inputs->push_back(f.hash());
        for (const v1::PrecomputedTable& t : spec.tables()) inputs->push_back(t.hash());
    }
    const int64_t first = job->first_task_id, last = job->first_task_id + job->tasks_total - 1;
    SqliteStatement results = db_.Prepare(
        "SELECT result_hash FROM tasks WHERE id BETWEEN ?1 AND ?2 AND result_hash <> ''");
    results.Bind(first, last);
    while (results.Step()) outputs->push_back(results.Text(0));
    SqliteStatement artifacts =
        db_.Prepare("SELECT artifact_hash FROM stages WHERE job_id = ?1 AND artifact_hash <> ''");
    artifacts.Bind(job_id);
    while (artifacts.Step()) outputs->push_back(artifacts.Text(0));
    db_.Prepare("DELETE FROM tasks WHERE id BETWEEN ?1 AND ?2").Bind(first, last).Run();
    for (const char* table : {"stages", "frames", "failures", "job_log"})
        db_.Prepare(std::string("DELETE FROM ") + table + " WHERE job_id = ?1").Bind(job_id).Run();
    db_.Prepare("DELETE FROM jobs WHERE id = ?1").Bind(job_id).Run();
}

std::vector<std::pair<std::string, std::array<int64_t, 5>>> Store::TaskCountsByStage(
    int64_t first_task_id, int64_t last_task_id) {
    SqliteStatement q = db_.Prepare(
        "SELECT stage, state, COUNT(*) FROM tasks WHERE id BETWEEN ?1 AND ?2 "
        "GROUP BY stage_index, stage, state ORDER BY stage_index");
    q.Bind(first_task_id, last_task_id);
    std::vector<std::pair<std::string, std::array<int64_t, 5>>> out;
    while (q.Step()) {
        const std::string stage = q.Text(0);
        const int64_t state = q.Int(1);
        if (out.empty() || out.back().first != stage) out.push_back({stage, {}});
        if (state >= 0 && state < 5) out.back().second[state] += q.Int(2);
    }
    return out;
}

std::vector<std::pair<int, int64_t>> Store::JobCountsByState() {
    SqliteStatement q = db_.Prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state");
    std::vector<std::pair<int, int64_t>> out;
    while (q.Step()) out.emplace_back(int(q.Int(0)), q.Int(1));
    return out;
}

std::vector<int64_t> Store::JobsFinishedBefore(int64_t ms) {
    SqliteStatement q = db_.Prepare(
        "SELECT id FROM jobs WHERE state IN (?1, ?2, ?3) AND finished_ms > 0 AND finished_ms < ?4 "
        "ORDER BY id");
    q.Bind(int(v1::JOB_STATE_DONE), int(v1::JOB_STATE_FAILED), int(v1::JOB_STATE_CANCELLED), ms);
    std::vector<int64_t> ids;
    while (q.Step()) ids.push_back(q.Int(0));
    return ids;
}

}  // namespace tessera

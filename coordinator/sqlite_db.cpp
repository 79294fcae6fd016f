#include "sqlite_db.h"

#include <stdexcept>
#include <utility>

#include "disk_space.h"

namespace tessera {

namespace {

// A full disk (SQLITE_FULL, or an I/O error whose cause is ENOSPC or EDQUOT) is
// NoSpaceError naming the database file; anything else std::runtime_error.
[[noreturn]] void ThrowSqliteError(sqlite3* db, int rc, const std::string& message) {
    const int primary = rc & 0xff;
    if (primary == SQLITE_FULL ||
        (primary == SQLITE_IOERR && IsNoSpaceErrno(sqlite3_system_errno(db)))) {
        const char* file = sqlite3_db_filename(db, "main");
        ThrowNoSpace(file && *file ? file : "the database", "SQLite: " + message);
    }
    throw std::runtime_error("SQLite: " + message);
}

}  // namespace

SqliteStatement::SqliteStatement(sqlite3* db, std::string_view sql) : db_(db) {
    int rc = sqlite3_prepare_v3(db, sql.data(), static_cast<int>(sql.size()),
                                SQLITE_PREPARE_PERSISTENT, &stmt_, nullptr);
    if (rc != SQLITE_OK)
        throw std::runtime_error("SQLite cannot prepare '" + std::string(sql) +
                                 "': " + sqlite3_errmsg(db));
}

SqliteStatement::~SqliteStatement() { sqlite3_finalize(stmt_); }

SqliteStatement::SqliteStatement(SqliteStatement&& other) noexcept
    : db_(other.db_), stmt_(std::exchange(other.stmt_, nullptr)) {}

SqliteStatement& SqliteStatement::operator=(SqliteStatement&& other) noexcept {
    if (this != &other) {
        sqlite3_finalize(stmt_);
        db_ = other.db_;
        stmt_ = std::exchange(other.stmt_, nullptr);
    }
    return *this;
}

void SqliteStatement::Check(int rc) const {
    if (rc != SQLITE_OK) ThrowSqliteError(db_, rc, sqlite3_errmsg(db_));
}

void SqliteStatement::Reset() { sqlite3_reset(stmt_); }

void SqliteStatement::BindOne(int index, int64_t v) { Check(sqlite3_bind_int64(stmt_, index, v)); }

void SqliteStatement::BindOne(int index, double v) { Check(sqlite3_bind_double(stmt_, index, v)); }

void SqliteStatement::BindOne(int index, std::string_view v) {
    Check(sqlite3_bind_text64(stmt_, index, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
}

void SqliteStatement::BindOne(int index, const SqliteBlobArg& v) {
    Check(sqlite3_bind_blob64(stmt_, index, v.bytes.data(), v.bytes.size(), SQLITE_TRANSIENT));
}

bool SqliteStatement::Step() {
    int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) {
        sqlite3_reset(stmt_);
        return false;
    }
    std::string message = sqlite3_errmsg(db_);
    const int system_errno = sqlite3_system_errno(db_);
    sqlite3_reset(stmt_);
    if ((rc & 0xff) == SQLITE_IOERR && IsNoSpaceErrno(system_errno)) rc = SQLITE_FULL;
    ThrowSqliteError(db_, rc, message);
}

void SqliteStatement::Run() {
    while (Step()) {
    }
}

int64_t SqliteStatement::Int(int column) const { return sqlite3_column_int64(stmt_, column); }

double SqliteStatement::Double(int column) const { return sqlite3_column_double(stmt_, column); }

std::string SqliteStatement::Text(int column) const {
    const unsigned char* text = sqlite3_column_text(stmt_, column);
    return text ? std::string(reinterpret_cast<const char*>(text),
                              static_cast<size_t>(sqlite3_column_bytes(stmt_, column)))
                : std::string();
}

std::string SqliteStatement::Blob(int column) const {
    const void* data = sqlite3_column_blob(stmt_, column);
    return data ? std::string(static_cast<const char*>(data),
                              static_cast<size_t>(sqlite3_column_bytes(stmt_, column)))
                : std::string();
}

bool SqliteStatement::IsNull(int column) const {
    return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}

SqliteDb::SqliteDb(const std::string& path) {
    int rc =
        sqlite3_open_v2(path.c_str(), &db_,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
        std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
        sqlite3_close_v2(db_);
        throw std::runtime_error("cannot open database " + path + ": " + message);
    }
    sqlite3_busy_timeout(db_, 5000);
}

SqliteDb::~SqliteDb() { sqlite3_close_v2(db_); }

void SqliteDb::Exec(const std::string& sql) {
    char* error = nullptr;
    if (const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error); rc != SQLITE_OK) {
        std::string message = error ? error : sqlite3_errmsg(db_);
        sqlite3_free(error);
        ThrowSqliteError(db_, rc, message + " (in: " + sql.substr(0, 80) + ")");
    }
}

SqliteTransaction::SqliteTransaction(SqliteDb& db) : db_(db) { db_.Exec("BEGIN IMMEDIATE"); }

SqliteTransaction::~SqliteTransaction() {
    if (!done_) {
        try {
            db_.Exec("ROLLBACK");
        } catch (...) {
            // A failed rollback leaves SQLite to roll back when the connection closes.
        }
    }
}

void SqliteTransaction::Commit() {
    db_.Exec("COMMIT");
    done_ = true;
}

}  // namespace tessera

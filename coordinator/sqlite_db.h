#pragma once

// A thin RAII layer over the SQLite C API: one connection, prepared statements with
// typed binding, and a transaction guard. Errors throw std::runtime_error with
// SQLite's message, except a full disk (SQLITE_FULL, or an I/O error caused by ENOSPC or
// EDQUOT): NoSpaceError naming the database file (disk_space.h). Not thread-safe: the
// owner serialises access.

#include <sqlite3.h>

#include <cstdint>
#include <string>
#include <string_view>

namespace tessera {

// A blob argument (Bind() binds strings as text otherwise).
struct SqliteBlobArg {
    std::string_view bytes;
};

class SqliteStatement {
  public:
    SqliteStatement() = default;
    SqliteStatement(sqlite3* db, std::string_view sql);
    ~SqliteStatement();
    SqliteStatement(SqliteStatement&& other) noexcept;
    SqliteStatement& operator=(SqliteStatement&& other) noexcept;
    SqliteStatement(const SqliteStatement&) = delete;
    SqliteStatement& operator=(const SqliteStatement&) = delete;

    // Resets the statement and binds the arguments to ?1, ?2, ...
    template <typename... Args>
    SqliteStatement& Bind(const Args&... args) {
        Reset();
        int index = 1;
        (BindOne(index++, args), ...);
        return *this;
    }
    // Steps once: true while a row is available. At the end the statement resets
    // itself; a caller that stops early calls Reset(), so that no read stays open
    // (an open read would keep the WAL from being checkpointed).
    bool Step();
    void Reset();
    // Steps to completion (for statements without result rows).
    void Run();

    int64_t Int(int column) const;
    double Double(int column) const;
    std::string Text(int column) const;
    std::string Blob(int column) const;
    bool IsNull(int column) const;

  private:
    void BindOne(int index, int64_t v);
    void BindOne(int index, int v) { BindOne(index, static_cast<int64_t>(v)); }
    void BindOne(int index, uint64_t v) { BindOne(index, static_cast<int64_t>(v)); }
    void BindOne(int index, double v);
    void BindOne(int index, const SqliteBlobArg& v);
    void BindOne(int index, std::string_view v);
    void BindOne(int index, const std::string& v) { BindOne(index, std::string_view(v)); }
    void BindOne(int index, const char* v) { BindOne(index, std::string_view(v)); }
    void Check(int rc) const;

    sqlite3* db_ = nullptr;
    sqlite3_stmt* stmt_ = nullptr;
};

class SqliteDb {
  public:
    // Opens (creating) the database file. Throws std::runtime_error naming the file.
    explicit SqliteDb(const std::string& path);
    ~SqliteDb();
    SqliteDb(const SqliteDb&) = delete;
    SqliteDb& operator=(const SqliteDb&) = delete;

    void Exec(const std::string& sql);
    SqliteStatement Prepare(std::string_view sql) { return SqliteStatement(db_, sql); }
    int64_t Changes() const { return sqlite3_changes64(db_); }
    int64_t LastInsertRowid() const { return sqlite3_last_insert_rowid(db_); }
    sqlite3* Handle() const { return db_; }

  private:
    sqlite3* db_ = nullptr;
};

// BEGIN IMMEDIATE on construction; ROLLBACK unless Commit() was called.
class SqliteTransaction {
  public:
    explicit SqliteTransaction(SqliteDb& db);
    ~SqliteTransaction();
    SqliteTransaction(const SqliteTransaction&) = delete;
    SqliteTransaction& operator=(const SqliteTransaction&) = delete;
    void Commit();

  private:
    SqliteDb& db_;
    bool done_ = false;
};

}  // namespace tessera

#pragma once

// The mission file's schema (docs/mission-file.md): its identity, its tables, and how a Mission
// is written to them and read back with every value checked. Internal to saker_mission (not part
// of its public API): MissionStore is the interface.

#include "core/mission/mission.h"
#include "core/mission/sqlite.h"
#include "core/util/status.h"

#include <string>

namespace saker::mission::schema {

// Checks the file's first bytes before SQLite touches it, so a foreign file never gets WAL side
// files and the messages say what the file is: NotFound, or InvalidData for an empty file, a
// file that is not an SQLite database, or one without the mission application_id.
Status CheckFileHeader(const std::string& path);
// Whether the open database is a Saker mission this build reads (identity, schema version, every
// table): its schema version, or InvalidData / Unsupported. Reads only.
StatusOr<int> CheckIdentity(const sqlite::Database& db);

// Sets the identity and creates the tables of schema kSchemaVersion in an empty database, in one
// transaction.
Status Create(const sqlite::Database& db);
// Brings a file of schema `schema` to kSchemaVersion, in one transaction.
Status Upgrade(const sqlite::Database& db, int schema);

// Why the header of `mission` breaks a rule of the file (empty when it does not). Save refuses
// such a mission and Load such a file, so the store never writes what it would not read.
std::string HeaderProblem(const Mission& mission);
// Why the parts of `mission` named by `parts` (SavePart bits) cannot be saved (empty when they
// can).
std::string PartsProblem(const Mission& mission, unsigned parts);

// Why the reviews and bookmarks of `mission` cannot be saved (empty when they can): order,
// values, note lengths.
std::string ReviewsProblem(const Mission& mission);

// Writes the header and replaces the parts named by `parts`, in one transaction. The caller has
// checked HeaderProblem and PartsProblem.
Status Save(const sqlite::Database& db, const Mission& mission, unsigned parts);
// Replaces the reviews and bookmarks only, in one transaction (the caller has checked
// ReviewsProblem).
Status SaveReviews(const sqlite::Database& db, const Mission& mission);
// Reads the whole mission except the tile images from a file of schema `schema`, in one read
// transaction; InvalidData naming the table, row and column at the first broken rule.
Status Load(const sqlite::Database& db, int schema, Mission* mission);

}  // namespace saker::mission::schema

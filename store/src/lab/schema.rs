//! The lab store's schema checked as a station's file's is (`damage`): every
//! table with every column and every named index that the migrations up to
//! its version make, and the role's privilege to read them (pushing, a
//! privilege missing is met by the write, which says what to grant). The expected set is the station's, made in memory from the
//! SQLite migrations with the same versions (the lab store has no migration
//! 7: the sample packs and SQLite's triggers are the station's own; a test
//! of tests/cli/lab.rs holds the two schemas equal). Read from PostgreSQL's
//! catalog (`pg_class`, `pg_attribute`), which shows every table whatever
//! the role may do with it, so a table the role may not read is named as
//! such, not as missing.

use super::MIGRATIONS;
use crate::NotFound;
use crate::damage::{Shape, expected};
use sqlx::Row as _;

/// What the lab store's migrations up to `version` make.
fn made(version: i64) -> anyhow::Result<Shape> {
    let packs = expected(7)?.without(&expected(6)?);
    Ok(expected(version)?.without(&packs))
}

/// The migration of the lab store that makes what `missing` (one entry of
/// [`Shape::missing_from`]) names, as its file.
fn made_by(missing: &str, found: &Shape) -> anyhow::Result<Option<String>> {
    for &(v, description, _) in MIGRATIONS {
        if made(v)?.missing_from(found).iter().any(|m| m == missing) {
            return Ok(Some(format!("migrations/postgres/{v:04}_{}.sql", description.replace(' ', "_"))));
        }
    }
    Ok(None)
}

/// The tables and indexes of the lab store's schema (the connection's
/// current schema), with the tables the role may not read.
async fn found(pool: &sqlx::PgPool) -> Result<(Shape, Vec<String>), sqlx::Error> {
    let rows = sqlx::query(
        "SELECT c.relname::text AS name, c.relkind::text AS kind, a.attname::text AS column_name, \
         CASE WHEN c.relkind IN ('r', 'p') THEN has_table_privilege(c.oid, 'SELECT') ELSE true END AS allowed \
         FROM pg_class AS c JOIN pg_namespace AS n ON n.oid = c.relnamespace \
         LEFT JOIN pg_attribute AS a ON a.attrelid = c.oid AND a.attnum > 0 AND NOT a.attisdropped \
         AND c.relkind IN ('r', 'p') \
         WHERE n.nspname = current_schema() AND c.relkind IN ('r', 'p', 'i')",
    )
    .fetch_all(pool)
    .await?;
    let mut shape = Shape::default();
    let mut denied = Vec::new();
    for row in rows {
        let name: String = row.try_get("name")?;
        let kind: String = row.try_get("kind")?;
        if kind == "i" {
            shape.add_index(&name);
            continue;
        }
        shape.add_column(&name, row.try_get::<Option<String>, _>("column_name")?.as_deref());
        if !row.try_get::<bool, _>("allowed")? && !denied.contains(&name) {
            denied.push(name);
        }
    }
    Ok((shape, denied))
}

/// Check the lab store's schema of `version` (see the module's
/// documentation): a missing table, column or index is the store's damage,
/// a table the role `user` may not read (not when `pushing`: the write
/// says what to grant) a grant to make; either is bad input naming what and what to run ([`NotFound`]).
pub(super) async fn check(
    pool: &sqlx::PgPool,
    shown: &str,
    user: &str,
    version: i64,
    pushing: bool,
) -> anyhow::Result<()> {
    let (shape, denied) = found(pool).await?;
    let expected = made(version)?;
    let mut said = Vec::new();
    for missing in expected.missing_from(&shape) {
        match made_by(&missing, &shape)? {
            Some(file) => said.push(format!("{missing} (made by {file})")),
            None => said.push(missing),
        }
    }
    if !said.is_empty() {
        return Err(NotFound(format!(
            "the lab store {shown} is damaged: {}; nothing was read from it or written to it: restore it from a \
             backup, or have its owner make what is missing as the migration named does (docs/lab.md)",
            said.join("; ")
        ))
        .into());
    }
    // Pushing, a privilege missing is met by the write, whose refusal says
    // what to grant for tables and sequences both (`in_words`).
    let ours: Vec<&String> = denied.iter().filter(|t| expected.table_names().any(|n| n == t.as_str())).collect();
    if !ours.is_empty() && !pushing {
        let tables = ours.iter().map(|t| format!("`{t}`")).collect::<Vec<_>>().join(", ");
        let names = ours.iter().map(|t| t.as_str()).collect::<Vec<_>>().join(", ");
        return Err(NotFound(format!(
            "the role {user} may not read the tables {tables} of the lab store {shown}: have its owner run `GRANT \
             SELECT ON {names} TO {user}`, or for every table `GRANT SELECT ON ALL TABLES IN SCHEMA public TO {user}` \
             (docs/lab.md, \"Roles\")"
        ))
        .into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lab_store_s_expected_schema_lacks_the_packs_and_names_each_object_s_migration() {
        let latest = MIGRATIONS.last().unwrap().0;
        let shape = made(latest).unwrap();
        let tables: Vec<&str> = shape.table_names().collect();
        assert!(!tables.contains(&"sample_packs") && tables.contains(&"certificates"), "{tables:?}");
        let mut found = shape.clone();
        found = found.without(&Shape::default());
        let missing = shape.missing_from(&found);
        assert!(missing.is_empty(), "{missing:?}");
        let empty = Shape::default();
        assert_eq!(
            made_by("the table `events` is missing", &empty).unwrap().as_deref(),
            Some("migrations/postgres/0001_init.sql")
        );
        assert_eq!(
            made_by("the table `certificates` is missing", &empty).unwrap().as_deref(),
            Some("migrations/postgres/0011_certificates.sql")
        );
    }
}

//! The users of `--auth FILE`: their names and argon2id hashes, read and
//! checked once at start; a password checked against them; and the hash
//! `survey serve --hash-password` prints.
//!
//! ```toml
//! [[user]]
//! name = "lab"
//! password_hash = "$argon2id$v=19$m=19456,t=2,p=1$..."
//! ```
//!
//! A file that cannot be used is refused with its path, line and key, and
//! never with a hash or a password in the message.

use argon2::password_hash::{PasswordHash, PasswordHasher as _, SaltString};
use argon2::{Algorithm, Argon2, Params};
use serde::Deserialize;
use std::path::Path;
use toml::Spanned;

/// The largest memory cost a hash in the file may ask for, KiB (a hash
/// asking for more would let every login take that much memory).
pub const MAX_MEMORY_KIB: u32 = 256 * 1024;
/// The largest time cost (passes) a hash in the file may ask for.
pub const MAX_PASSES: u32 = 16;
/// The largest parallelism (lanes) a hash in the file may ask for.
pub const MAX_LANES: u32 = 16;

/// An auth file that cannot be used: the file, its line (where known), the
/// key concerned and what is wrong.
#[derive(Debug)]
pub struct AuthFileError {
    pub file: String,
    pub line: Option<usize>,
    pub key: String,
    pub message: String,
}

impl std::fmt::Display for AuthFileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.key.is_empty() {
            write!(f, ": {}", self.key)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for AuthFileError {}

/// One user of the file.
#[derive(Debug, Clone)]
pub struct User {
    pub name: String,
    /// The PHC string (`$argon2id$v=19$...`), checked to parse.
    hash: String,
}

/// The users of an auth file.
#[derive(Debug, Clone)]
pub struct Users {
    users: Vec<User>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDoc {
    #[serde(default)]
    user: Vec<Spanned<UserDoc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UserDoc {
    name: Spanned<String>,
    password_hash: Spanned<String>,
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The key an error concerns: named in a serde message (``unknown field
/// `x` `` or ``missing field `x` ``), else the key of its line (`k` in `k = ...`).
fn key_in(message: &str, text: &str, offset: Option<usize>) -> String {
    let named = ["unknown field", "missing field", "duplicate key"].iter().any(|m| message.starts_with(m));
    let key = if named {
        message.split('`').nth(1).unwrap_or_default()
    } else {
        let Some(offset) = offset.map(|o| o.min(text.len())) else { return String::new() };
        let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
        let line = text[start..].lines().next().unwrap_or_default();
        line.split_once('=').map_or("", |(k, _)| k.trim())
    };
    let bare = key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare && key.len() <= 64 { key.to_string() } else { String::new() }
}

impl Users {
    /// Read and check the auth file at `path`.
    pub fn read(path: &Path) -> Result<Users, AuthFileError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| AuthFileError {
            file: file.clone(),
            line: None,
            key: String::new(),
            message: format!("cannot read the auth file: {}", survey_words(&e)),
        })?;
        Users::parse(&text, &file)
    }

    /// Parse and check an auth file's `text`; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Users, AuthFileError> {
        let err = |line: Option<usize>, key: &str, message: String| AuthFileError {
            file: file.to_string(),
            line,
            key: key.to_string(),
            message,
        };
        let doc: FileDoc = toml::from_str(text).map_err(|e| {
            // The message alone: toml's Display quotes the file's text, which may hold a hash.
            let message = e.message().trim().to_string();
            let at = e.span().map(|s| s.start);
            err(at.map(|s| line_of(text, s)), &key_in(&message, text, at), message)
        })?;
        if doc.user.is_empty() {
            return Err(err(
                None,
                "user",
                "no [[user]]: add one with `name` and the `password_hash` that `survey serve --hash-password` prints"
                    .into(),
            ));
        }
        let mut users: Vec<User> = Vec::new();
        for entry in doc.user {
            let entry = entry.into_inner();
            let (name, name_at) = (entry.name.get_ref().clone(), line_of(text, entry.name.span().start));
            let hash_at = line_of(text, entry.password_hash.span().start);
            check_name(&name).map_err(|m| err(Some(name_at), "user.name", m))?;
            if users.iter().any(|u| u.name == name) {
                return Err(err(Some(name_at), "user.name", format!("the user {name:?} is named twice")));
            }
            let hash = entry.password_hash.into_inner();
            check_hash(&hash).map_err(|m| err(Some(hash_at), "user.password_hash", m))?;
            users.push(User { name, hash });
        }
        Ok(Users { users })
    }

    /// The users' names.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.users.iter().map(|u| u.name.as_str())
    }

    /// Whether `password` is `name`'s. Takes an argon2 hash's time whether
    /// the name is known or not (an unknown name is checked against a hash
    /// of nothing anyone knows), so the time tells nobody which names exist.
    pub fn check(&self, name: &str, password: &str) -> bool {
        self.check_in(name, password, &mut Vec::new())
    }

    /// [`Users::check`] in the argon2 memory `blocks` (grown as a hash
    /// needs, and kept by the caller for the next check: no allocation of
    /// tens of MiB per login).
    pub fn check_in(&self, name: &str, password: &str, blocks: &mut Vec<argon2::Block>) -> bool {
        let (hash, known) = match self.users.iter().find(|u| u.name == name) {
            Some(u) => (u.hash.as_str(), true),
            None => (DECOY, false),
        };
        let Ok(parsed) = PasswordHash::new(hash) else { return false };
        let (Ok(params), Some(expected), Some(salt)) = (Params::try_from(&parsed), parsed.hash, parsed.salt) else {
            return false;
        };
        let mut salt_bytes = [0u8; 64];
        let Ok(salt) = salt.decode_b64(&mut salt_bytes) else { return false };
        if blocks.len() < params.block_count() {
            blocks.resize(params.block_count(), argon2::Block::default());
        }
        let mut out = [0u8; 64];
        let Some(out) = out.get_mut(..expected.len()) else { return false };
        let argon = Argon2::new(Algorithm::Argon2id, argon2::Version::V0x13, params);
        let hashed = argon.hash_password_into_with_memory(password.as_bytes(), salt, &mut *out, &mut blocks[..]);
        // `Output`'s comparison takes the same time wherever the bytes differ.
        let ok = hashed.is_ok() && argon2::password_hash::Output::new(out).is_ok_and(|o| o == expected);
        ok && known
    }
}

/// A hash no password is known for (of 32 random bytes, thrown away), with
/// the default parameters: what an unknown name is checked against.
const DECOY: &str = "$argon2id$v=19$m=19456,t=2,p=1$aw9UfmWy8Ff1VZ3IHDfEOw$9gY8jIA0xJsDhWaJK7xX7aXc4y9YlxHfzCRIVOLh6ZU";

/// An I/O error in words (no `(os error N)`).
fn survey_words(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".into(),
        std::io::ErrorKind::PermissionDenied => "permission denied".into(),
        _ => {
            let text = e.to_string();
            text.split(" (os error").next().unwrap_or(&text).to_string()
        }
    }
}

/// A user's name: 1-64 characters, none a control character or `:` (HTTP
/// Basic separates the name from the password with `:`).
fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() || name.chars().count() > 64 {
        return Err("a name is 1 to 64 characters".into());
    }
    if name.chars().any(|c| c.is_control() || c == ':') {
        return Err("a name holds no control character and no ':'".into());
    }
    Ok(())
}

/// A hash the server can check: argon2id, version 19, its costs within bounds.
fn check_hash(hash: &str) -> Result<(), String> {
    let what = "not an argon2id hash (`$argon2id$v=19$m=...,t=...,p=...$SALT$HASH`): make one with `survey serve \
                --hash-password`";
    let parsed = PasswordHash::new(hash).map_err(|_| what.to_string())?;
    if parsed.algorithm != Algorithm::Argon2id.ident() || parsed.hash.is_none() || parsed.salt.is_none() {
        return Err(what.into());
    }
    if parsed.version != Some(0x13) {
        return Err("an argon2id hash of version 19 (`v=19`) is needed".into());
    }
    let params = Params::try_from(&parsed).map_err(|_| what.to_string())?;
    if params.m_cost() > MAX_MEMORY_KIB || params.t_cost() > MAX_PASSES || params.p_cost() > MAX_LANES {
        return Err(format!(
            "its costs (m={}, t={}, p={}) exceed what this server checks at every login (m<={MAX_MEMORY_KIB}, \
             t<={MAX_PASSES}, p<={MAX_LANES})",
            params.m_cost(),
            params.t_cost(),
            params.p_cost()
        ));
    }
    Ok(())
}

/// The PHC string of `password`: argon2id, version 19, the crate's default
/// costs (19 MiB, 2 passes, 1 lane: OWASP's recommended minimum), a random
/// 16-byte salt.
pub fn hash_password(password: &str) -> anyhow::Result<String> {
    let mut salt = [0u8; 16];
    getrandom::fill(&mut salt).map_err(|e| anyhow::anyhow!("no random numbers from the system: {e}"))?;
    let salt = SaltString::encode_b64(&salt).map_err(|e| anyhow::anyhow!("the salt: {e}"))?;
    let hash = Argon2::default()
        .hash_password(password.as_bytes(), &salt)
        .map_err(|e| anyhow::anyhow!("hashing the password: {e}"))?;
    Ok(hash.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hash_made_here_checks_its_password_only() {
        let hash = hash_password("correct horse").unwrap();
        assert!(hash.starts_with("$argon2id$v=19$m=19456,t=2,p=1$"), "{hash}");
        let users =
            Users::parse(&format!("[[user]]\nname = \"lab\"\npassword_hash = \"{hash}\"\n"), "auth.toml").unwrap();
        assert!(users.check("lab", "correct horse"));
        use argon2::password_hash::PasswordVerifier as _;
        assert!(Argon2::default().verify_password(b"correct horse", &PasswordHash::new(&hash).unwrap()).is_ok());
        assert!(!users.check("lab", "correct horse "));
        assert!(!users.check("other", "correct horse"));
        assert_eq!(users.names().collect::<Vec<_>>(), ["lab"]);
    }

    #[test]
    fn the_decoy_is_a_usable_hash() {
        assert!(check_hash(DECOY).is_ok());
        assert!(!Users { users: vec![] }.check("x", ""));
    }

    #[test]
    fn a_bad_file_is_refused_with_its_line_and_key_and_no_hash() {
        let good = "$argon2id$v=19$m=19456,t=2,p=1$aw9UfmWy8Ff1VZ3IHDfEOw$9gY8jIA0xJsDhWaJK7xX7aXc4y9YlxHfzCRIVOLh6ZU";
        let cases: Vec<(String, Option<usize>, &str)> = vec![
            ("".into(), None, "user"),
            (format!("[[user]]\nname = \"lab\"\npasword_hash = \"{good}\"\n"), Some(3), "pasword_hash"),
            ("[[user]]\nname = \"lab\"\n".into(), Some(1), "password_hash"),
            (format!("[[user]]\nname = \"a:b\"\npassword_hash = \"{good}\"\n"), Some(2), "user.name"),
            (format!("[[user]]\nname = \"\"\npassword_hash = \"{good}\"\n"), Some(2), "user.name"),
            ("[[user]]\nname = \"lab\"\npassword_hash = \"$2b$12$secretsecretsecret\"\n".into(), Some(3), "user.password_hash"),
            (
                "[[user]]\nname = \"lab\"\npassword_hash = \"$argon2i$v=19$m=19456,t=2,p=1$aw9UfmWy8Ff1VZ3IHDfEOw$9gY8jIA0xJsDhWaJK7xX7aXc4y9YlxHfzCRIVOLh6ZU\"\n"
                    .into(),
                Some(3),
                "user.password_hash",
            ),
            (
                "[[user]]\nname = \"lab\"\npassword_hash = \"$argon2id$v=19$m=4194304,t=2,p=1$aw9UfmWy8Ff1VZ3IHDfEOw$9gY8jIA0xJsDhWaJK7xX7aXc4y9YlxHfzCRIVOLh6ZU\"\n"
                    .into(),
                Some(3),
                "user.password_hash",
            ),
            (
                format!("[[user]]\nname = \"lab\"\npassword_hash = \"{good}\"\n[[user]]\nname = \"lab\"\npassword_hash = \"{good}\"\n"),
                Some(5),
                "user.name",
            ),
            (format!("[[user]]\nname = \"lab\"\npassword_hash = \"{good}\n"), Some(3), "password_hash"),
        ];
        for (text, line, key) in cases {
            let e = Users::parse(&text, "auth.toml").unwrap_err();
            let said = e.to_string();
            assert_eq!((e.line, e.key.as_str()), (line, key), "{text}\n{said}");
            assert!(said.starts_with("auth.toml"), "{said}");
            assert!(!said.contains("aw9UfmWy8") && !said.contains("secretsecret"), "a hash said: {said}");
        }
    }
}

//! Manifold files: the versioned binary format and CSV.
//!
//! **Binary** (`.manifold`, little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 16 | magic `PEGTWIN-MANIFOLD` |
//! | 4 | format version, `u32` (this build writes and reads [`FORMAT_VERSION`]) |
//! | 4 | length L of the metadata, `u32` |
//! | L | metadata, JSON ([`ManifoldMeta`]) |
//! | 8 | point count N, `u64` |
//! | 48 N | poses `hole_T_peg`, 6 x `f64` each: x, y, z (m), roll, pitch, yaw (rad) |
//! | 48 N | unit normals in scaled coordinates, 6 x `f64` each |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! The k-d tree is rebuilt on load (tens of milliseconds for 10⁵ points).
//!
//! **CSV** (for numpy and other tools): a header `x,y,z,roll,pitch,yaw`, optionally followed by
//! `nx,ny,nz,nroll,npitch,nyaw` (unit normals in scaled coordinates), then one pose per row in
//! metres and radians. Observation files use the same six pose columns.
//!
//! Files are written to a temporary name beside the target and renamed, so a failure never leaves a
//! half-written file.

use super::{Manifold, ManifoldMeta};
use crate::error::{Error, Result};
use crate::pose::Pose6;
use std::path::Path;

/// Magic bytes at the start of a binary manifold file.
pub const MAGIC: &[u8; 16] = b"PEGTWIN-MANIFOLD";
/// The binary format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Column names of a pose in CSV files.
pub const POSE_COLUMNS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
/// Column names of a normal in CSV files.
pub const NORMAL_COLUMNS: [&str; 6] = ["nx", "ny", "nz", "nroll", "npitch", "nyaw"];

/// Save a manifold in the binary format.
pub fn save(manifold: &Manifold, path: &Path) -> Result<()> {
    let meta = serde_json::to_vec(&manifold.meta).expect("metadata serialises");
    let n = manifold.len();
    let mut bytes = Vec::with_capacity(36 + meta.len() + 96 * n);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&(meta.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&meta);
    bytes.extend_from_slice(&(n as u64).to_le_bytes());
    for p in &manifold.points {
        p.0.iter()
            .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    }
    for nrm in &manifold.normals {
        nrm.iter()
            .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    }
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    crate::files::write_atomically(path, &bytes)
}

/// A cursor over the bytes of a binary manifold that names the file in its errors.
struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(Error::file(
                self.path,
                format!("truncated: the file ends inside the {what}"),
            ));
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }

    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }

    fn rows(&mut self, n: usize, what: &str) -> Result<Vec<[f64; 6]>> {
        let bytes = self.take(n.saturating_mul(48), what)?;
        Ok(bytes
            .chunks_exact(48)
            .map(|c| {
                std::array::from_fn(|i| f64::from_le_bytes(c[8 * i..8 * i + 8].try_into().unwrap()))
            })
            .collect())
    }
}

/// Whether a file starts with the binary manifold's magic bytes.
pub fn is_binary(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 16];
    crate::files::open_input(path, u64::MAX).is_ok_and(|(mut f, _)| f.read_exact(&mut head).is_ok())
        && &head == MAGIC
}

/// Load a binary manifold, checking magic, checksum and version.
pub fn load(path: &Path) -> Result<Manifold> {
    let bytes = crate::files::read_input(path, crate::files::DATA_LIMIT_BYTES)?;
    if bytes.len() < 16 || &bytes[..16] != MAGIC {
        return Err(Error::file(
            path,
            "not a pegtwin manifold file (magic bytes missing): made by `manifold build` or \
             `manifold import`, or a CSV of poses named *.csv where a command takes CSV",
        ));
    }
    if bytes.len() < 28 {
        return Err(Error::file(path, "truncated: shorter than the file header"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes(tail.try_into().unwrap());
    let actual = crc32fast::hash(body);
    let mut r = Reader {
        path,
        bytes: body,
        at: 16,
    };
    let version = r.u32("version")?;
    if version != FORMAT_VERSION {
        return Err(Error::file(
            path,
            format!("format version {version}; this pegtwin reads version {FORMAT_VERSION}"),
        ));
    }
    if stored != actual {
        return Err(Error::file(
            path,
            format!(
                "checksum mismatch (stored {stored:08x}, computed {actual:08x}): the file is corrupt"
            ),
        ));
    }
    let meta_len = r.u32("metadata length")? as usize;
    let meta: ManifoldMeta = serde_json::from_slice(r.take(meta_len, "metadata")?)
        .map_err(|e| Error::file(path, format!("metadata: {e}")))?;
    let n = r.u64("point count")? as usize;
    let points = r.rows(n, "poses")?.into_iter().map(Pose6).collect();
    let normals = r.rows(n, "normals")?;
    if r.at != body.len() {
        return Err(Error::file(
            path,
            format!("{} unexpected bytes after the normals", body.len() - r.at),
        ));
    }
    Manifold::with_normals(points, normals, meta).map_err(|e| Error::file(path, e.to_string()))
}

/// Poses read from a CSV file, with normals when the file has the normal columns.
pub struct CsvPoses {
    pub poses: Vec<Pose6>,
    pub normals: Option<Vec<[f64; 6]>>,
}

/// Read a pose CSV (`x,y,z,roll,pitch,yaw` [+ `nx,...,nyaw`], metres and radians).
pub fn read_csv(path: &Path) -> Result<CsvPoses> {
    let (file, _) = crate::files::open_input(path, crate::files::DATA_LIMIT_BYTES)?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(file);
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| Error::file(path, format!("line 1: {e}")))?
        .iter()
        .map(str::to_string)
        .collect();
    let with_normals = header.len() == NORMAL_COLUMNS.len() + POSE_COLUMNS.len();
    let expected: Vec<&str> = if with_normals {
        POSE_COLUMNS
            .iter()
            .chain(NORMAL_COLUMNS.iter())
            .copied()
            .collect()
    } else {
        POSE_COLUMNS.to_vec()
    };
    if header != expected {
        return Err(Error::file(
            path,
            format!(
                "line 1: header is `{}`; expected `{}` (optionally followed by `,{}`)",
                header.join(","),
                POSE_COLUMNS.join(","),
                NORMAL_COLUMNS.join(",")
            ),
        ));
    }
    let mut poses = Vec::new();
    let mut normals = Vec::new();
    for record in rdr.records() {
        let record = record.map_err(|e| Error::file(path, csv_error_line(&e)))?;
        let line = record.position().map_or(0, |p| p.line());
        let mut values = [0.0; 12];
        for (k, (field, name)) in record.iter().zip(&expected).enumerate() {
            let v: f64 = field.parse().map_err(|_| {
                Error::file(
                    path,
                    format!("line {line}: {name} = `{field}` is not a number"),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::file(
                    path,
                    format!("line {line}: {name} = {field}; expected a finite number"),
                ));
            }
            values[k] = v;
        }
        poses.push(Pose6(values[..6].try_into().unwrap()));
        if with_normals {
            normals.push(values[6..].try_into().unwrap());
        }
    }
    Ok(CsvPoses {
        poses,
        normals: with_normals.then_some(normals),
    })
}

fn csv_error_line(e: &csv::Error) -> String {
    match e.position() {
        Some(p) => format!("line {}: {e}", p.line()),
        None => e.to_string(),
    }
}

/// Write poses (and normals, when given) as CSV.
pub fn write_csv(path: &Path, poses: &[Pose6], normals: Option<&[[f64; 6]]>) -> Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<&str> = POSE_COLUMNS.to_vec();
    if normals.is_some() {
        header.extend(NORMAL_COLUMNS);
    }
    let io = |e: csv::Error| Error::file(path, format!("cannot write: {e}"));
    w.write_record(&header).map_err(io)?;
    for (i, p) in poses.iter().enumerate() {
        let mut row: Vec<String> = p.0.iter().map(|v| v.to_string()).collect();
        if let Some(n) = normals {
            row.extend(n[i].iter().map(|v| v.to_string()));
        }
        w.write_record(&row).map_err(io)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| Error::file(path, format!("cannot write: {e}")))?;
    crate::files::write_atomically(path, &bytes)
}

/// Load a manifold from a binary file, or import it from a CSV file (`meta` describes a CSV
/// import; normals are computed when the CSV has none).
pub fn load_any(path: &Path, meta: ManifoldMeta) -> Result<Manifold> {
    if is_binary(path) {
        return load(path);
    }
    let is_csv = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    if !is_csv {
        return load(path);
    }
    let CsvPoses { poses, normals } = read_csv(path)?;
    let result = match normals {
        Some(n) => Manifold::with_normals(poses, n, meta),
        None => Manifold::from_points(poses, meta),
    };
    result.map_err(|e| Error::file(path, e.to_string()))
}

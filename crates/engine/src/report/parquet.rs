//! Parquet copies of simnet's CSV tables (`--format parquet`, cargo feature `parquet`): the same columns, each typed
//! from its cells — integers, floats, booleans, else text — nullable where a cell is empty, zstd pages, 65,536 rows
//! per row group. Two passes over the CSV (types, then rows), so memory stays bounded by one row group.

use std::path::Path;
use std::sync::Arc;

use parquet::basic::{Compression, LogicalType, Repetition, Type as Physical, ZstdLevel};
use parquet::data_type::{BoolType, ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

/// Rows per row group.
const GROUP: usize = 65_536;

#[derive(Debug, thiserror::Error)]
pub enum ParquetError {
    #[error("{}: {source}", path.display())]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    Csv {
        path: std::path::PathBuf,
        source: csv::Error,
    },
    #[error("{}: {source}", path.display())]
    Parquet {
        path: std::path::PathBuf,
        source: parquet::errors::ParquetError,
    },
}

/// A column's type, from every non-empty cell.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Int,
    Float,
    Bool,
    Text,
}

/// What the non-empty cells of a column seen so far could all be.
#[derive(Debug, Clone, Copy)]
struct Seen {
    any: bool,
    int: bool,
    float: bool,
    bool: bool,
}

impl Seen {
    fn new() -> Seen {
        Seen {
            any: false,
            int: true,
            float: true,
            bool: true,
        }
    }

    fn cell(&mut self, c: &str) {
        if c.is_empty() {
            return;
        }
        self.any = true;
        self.int &= c.parse::<i64>().is_ok();
        self.float &= c.parse::<f64>().is_ok();
        self.bool &= c == "true" || c == "false";
    }

    fn kind(self) -> Kind {
        match self {
            Seen { any: false, .. } => Kind::Text,
            Seen { int: true, .. } => Kind::Int,
            Seen { float: true, .. } => Kind::Float,
            Seen { bool: true, .. } => Kind::Bool,
            _ => Kind::Text,
        }
    }
}

/// `csv` (a header row, then rows) as the Parquet file `out`, written under a temporary name and renamed into place.
pub fn csv_to_parquet(csv: &Path, out: &Path) -> Result<(), ParquetError> {
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = out.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    let done = write(csv, &tmp).and_then(|()| {
        std::fs::rename(&tmp, out).map_err(|source| ParquetError::Io {
            path: out.to_path_buf(),
            source,
        })
    });
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

fn write(csv: &Path, out: &Path) -> Result<(), ParquetError> {
    let csv_err = |source| ParquetError::Csv {
        path: csv.to_path_buf(),
        source,
    };
    let pq_err = |source| ParquetError::Parquet {
        path: out.to_path_buf(),
        source,
    };
    // Pass 1: the columns' types (a column with no cell at all is text).
    let mut reader = csv::Reader::from_path(csv).map_err(csv_err)?;
    let header: Vec<String> = reader.headers().map_err(csv_err)?.iter().map(String::from).collect();
    let mut seen = vec![Seen::new(); header.len()];
    for rec in reader.records() {
        let rec = rec.map_err(csv_err)?;
        seen.iter_mut().zip(rec.iter()).for_each(|(s, cell)| s.cell(cell));
    }
    let kinds: Vec<Kind> = seen.into_iter().map(Seen::kind).collect();
    let fields = header
        .iter()
        .zip(&kinds)
        .map(|(name, k)| {
            let b = Type::primitive_type_builder(
                name,
                match k {
                    Kind::Int => Physical::INT64,
                    Kind::Float => Physical::DOUBLE,
                    Kind::Bool => Physical::BOOLEAN,
                    Kind::Text => Physical::BYTE_ARRAY,
                },
            )
            .with_repetition(Repetition::OPTIONAL);
            let b = if *k == Kind::Text {
                b.with_logical_type(Some(LogicalType::String))
            } else {
                b
            };
            b.build().map(Arc::new)
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(pq_err)?;
    let schema = Arc::new(
        Type::group_type_builder("schema")
            .with_fields(fields)
            .build()
            .map_err(pq_err)?,
    );
    let props = Arc::new(
        WriterProperties::builder()
            .set_compression(Compression::ZSTD(ZstdLevel::default()))
            .build(),
    );
    let file = std::fs::File::create(out).map_err(|source| ParquetError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let mut writer = SerializedFileWriter::new(std::io::BufWriter::new(file), schema, props).map_err(pq_err)?;
    // Pass 2: the rows, a row group at a time.
    let mut reader = csv::Reader::from_path(csv).map_err(csv_err)?;
    let mut rows: Vec<csv::StringRecord> = Vec::with_capacity(GROUP);
    let mut records = reader.records();
    loop {
        rows.clear();
        for rec in records.by_ref().take(GROUP) {
            rows.push(rec.map_err(csv_err)?);
        }
        if rows.is_empty() {
            break;
        }
        let mut group = writer.next_row_group().map_err(pq_err)?;
        let mut c = 0;
        while let Some(mut col) = group.next_column().map_err(pq_err)? {
            let cells = || rows.iter().map(|r| r.get(c).unwrap_or(""));
            let defs: Vec<i16> = cells().map(|s| i16::from(!s.is_empty())).collect();
            let present = || cells().filter(|s| !s.is_empty());
            // Every present cell was checked against its column's type in pass 1.
            match kinds[c] {
                Kind::Int => {
                    let v: Vec<i64> = present().map(|s| s.parse().unwrap_or_default()).collect();
                    col.typed::<Int64Type>().write_batch(&v, Some(&defs), None)
                }
                Kind::Float => {
                    let v: Vec<f64> = present().map(|s| s.parse().unwrap_or(f64::NAN)).collect();
                    col.typed::<DoubleType>().write_batch(&v, Some(&defs), None)
                }
                Kind::Bool => {
                    let v: Vec<bool> = present().map(|s| s == "true").collect();
                    col.typed::<BoolType>().write_batch(&v, Some(&defs), None)
                }
                Kind::Text => {
                    let v: Vec<ByteArray> = present().map(|s| ByteArray::from(s.as_bytes().to_vec())).collect();
                    col.typed::<ByteArrayType>().write_batch(&v, Some(&defs), None)
                }
            }
            .map_err(pq_err)?;
            col.close().map_err(pq_err)?;
            c += 1;
        }
        group.close().map_err(pq_err)?;
    }
    writer.close().map_err(pq_err)?;
    Ok(())
}

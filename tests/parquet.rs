//! Parquet read back. stiff writes and reads Parquet by its own code (`src/output/parquet.rs`, from the
//! format's specification); these tests check its reader against files another implementation wrote
//! (pyarrow, `tests/reference/parquet/README.md`), value for value and bit for bit, and that its writer's
//! tables read back as the CSV tables they were written from (`cli_surface.rs`). pyarrow and polars reading
//! stiff's files are checked by `scripts/crosscheck-parquet`.

use std::path::Path;

use assert_cmd::Command;
use stiff::output::parquet::read_columns;

fn stiff() -> Command {
    Command::cargo_bin("stiff").unwrap()
}

/// The text columns of the tables here; every other column is numeric.
const TEXTS: [&str; 3] = ["name", "status", "free_directions"];

/// Every cell of the Parquet table at `parquet`, read by stiff's reader, is the cell of the CSV table at
/// `csv`: a number the same f64 bit for bit (a count as a number), a text the same text, an empty cell a
/// null (NaN, or an empty text); the same columns in the same order and the same rows.
pub fn assert_columns_are_csv(parquet: &Path, csv: &Path) {
    let mut reader = csv::Reader::from_path(csv).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    let rows: Vec<Vec<String>> = reader.records().map(|r| r.unwrap().iter().map(String::from).collect()).collect();
    let read =
        read_columns(std::fs::File::open(parquet).unwrap(), &|_, c| !TEXTS.contains(&c), &|_, c| TEXTS.contains(&c))
            .unwrap();
    assert_eq!(read.header, header, "{}", parquet.display());
    assert_eq!(read.rows, rows.len());
    assert_eq!(read.numbers.len() + read.texts.len(), header.len(), "every column read");
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    for (name, values) in &read.numbers {
        let k = column(name);
        assert_eq!(values.len(), rows.len(), "{name}");
        for (row, (v, cells)) in values.iter().zip(&rows).enumerate() {
            let cell = &cells[k];
            let expected = if cell.is_empty() { f64::NAN } else { cell.parse::<f64>().unwrap() };
            assert_eq!(v.to_bits(), expected.to_bits(), "{} {name} row {row}: {v} for `{cell}`", parquet.display());
        }
    }
    for (name, values) in &read.texts {
        let k = column(name);
        let expected: Vec<&str> = rows.iter().map(|cells| cells[k].as_str()).collect();
        assert_eq!(values, &expected, "{} {name}", parquet.display());
    }
}

/// The value of `key` in a Parquet file's key-value metadata, found in its footer's bytes: the key's
/// bytes, then the value's field (Thrift compact: 0x18, a binary field one id on), its varint length, its
/// bytes.
pub fn footer_value(parquet: &Path, key: &str) -> String {
    let bytes = std::fs::read(parquet).unwrap();
    let footer_length = u32::from_le_bytes(bytes[bytes.len() - 8..bytes.len() - 4].try_into().unwrap()) as usize;
    let footer = &bytes[bytes.len() - 8 - footer_length..bytes.len() - 8];
    let at = footer.windows(key.len()).position(|w| w == key.as_bytes()).expect("the key") + key.len();
    assert_eq!(footer[at], 0x18, "the value's field header");
    let (mut length, mut shift, mut k) = (0usize, 0, at + 1);
    loop {
        length |= usize::from(footer[k] & 0x7F) << shift;
        shift += 7;
        k += 1;
        if footer[k - 1] & 0x80 == 0 {
            break;
        }
    }
    String::from_utf8(footer[k..k + length].to_vec()).unwrap()
}

fn reference(name: &str) -> std::path::PathBuf {
    Path::new("tests/reference/parquet").join(name)
}

/// A loaded map as pyarrow writes it (dictionary pages and version-1 data pages; PLAIN values in
/// version-2 pages; no compression), and a table of three row groups with nulls every seventh row: each
/// reads back as the CSV it was written from, bit for bit, its counts (uint64) as numbers and its nulls
/// as empty cells.
#[test]
fn parquet_tables_written_by_pyarrow_read_back_as_their_csv() {
    for variant in ["dictionary", "v2", "uncompressed"] {
        let parquet = reference(&format!("loaded-map-pyarrow-{variant}.parquet"));
        assert_columns_are_csv(&parquet, &reference("loaded-map.csv"));
    }
    assert_columns_are_csv(&reference("pages-pyarrow.parquet"), &reference("pages.csv"));
}

/// A Parquet table compressed by a codec stiff does not read (snappy, pyarrow's default) is refused with
/// the codec's name and what to do, and the same map written by pyarrow in zstd is drawn as its CSV.
#[test]
fn a_parquet_table_of_another_codec_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = stiff()
        .arg("plot")
        .arg(reference("loaded-map-pyarrow-snappy.parquet"))
        .arg("-o")
        .arg(dir.path().join("s.svg"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("snappy") && err.contains("zstd"), "{err}");
    let picture = |table: &Path, svg: &str| {
        let svg = dir.path().join(svg);
        stiff().arg("plot").arg(table).arg("-o").arg(&svg).assert().success();
        std::fs::read_to_string(svg).unwrap()
    };
    assert_eq!(
        picture(&reference("loaded-map-pyarrow-dictionary.parquet"), "p.svg"),
        picture(&reference("loaded-map.csv"), "c.svg")
    );
}

/// Damaged Parquet files (cut short anywhere, or with any one byte of the footer changed) give an error or
/// a table, never a panic: the reader checks every length and count against the bytes there are.
#[test]
fn a_damaged_parquet_file_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(reference("pages-pyarrow.parquet")).unwrap();
    let path = dir.path().join("d.parquet");
    let read = |b: &[u8]| {
        std::fs::write(&path, b).unwrap();
        let _ = read_columns(std::fs::File::open(&path).unwrap(), &|_, c| c != "status", &|_, c| c == "status");
    };
    for cut in (0..bytes.len()).step_by(97) {
        read(&bytes[..cut]);
    }
    let footer_length = u32::from_le_bytes(bytes[bytes.len() - 8..bytes.len() - 4].try_into().unwrap()) as usize;
    for k in (bytes.len() - 8 - footer_length..bytes.len()).step_by(3) {
        for v in [0x00, 0x7F, 0xFF, bytes[k] ^ 0x10] {
            let mut b = bytes.clone();
            b[k] = v;
            read(&b);
        }
    }
    let mut pages = bytes.clone();
    for k in (4..bytes.len() - 8 - footer_length).step_by(5) {
        pages[k] ^= 0x5A;
    }
    read(&pages);
}

//! CSV output for the studies, written by the `csv` crate so that a field
//! holding a comma or a quote (a master named "Jacobi, zero-order hold") is
//! quoted and every reader sees the header's columns.

use anyhow::{Context, Result};

/// A CSV table in memory: a header, then rows of exactly as many fields.
pub struct CsvTable {
    writer: csv::Writer<Vec<u8>>,
}

impl CsvTable {
    /// A table with these column names.
    pub fn new(header: &[&str]) -> Self {
        let mut writer = csv::Writer::from_writer(Vec::new());
        // Writing to memory cannot fail but for a wrong field count, which
        // the header (the first record) cannot have.
        writer.write_record(header).expect("a CSV header is written to memory");
        Self { writer }
    }

    /// Appends a row; an error when its field count is not the header's.
    pub fn row<I, S>(&mut self, fields: I) -> Result<()>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<[u8]>,
    {
        self.writer.write_record(fields).context("writing a CSV row")
    }

    /// The table as text.
    pub fn into_string(self) -> Result<String> {
        let bytes = self.writer.into_inner().context("finishing a CSV table")?;
        String::from_utf8(bytes).context("CSV table is not UTF-8")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_with_commas_and_quotes_read_back_as_written() {
        let mut t = CsvTable::new(&["master", "error"]);
        t.row(["Jacobi, zero-order hold", "1e-3"]).unwrap();
        t.row(["a \"quoted\" name", "2"]).unwrap();
        let text = t.into_string().unwrap();
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let rows: Vec<csv::StringRecord> = reader.records().collect::<Result<_, _>>().unwrap();
        assert_eq!(reader.headers().unwrap().len(), 2);
        assert_eq!(&rows[0][0], "Jacobi, zero-order hold");
        assert_eq!(&rows[1][0], "a \"quoted\" name");
        assert!(rows.iter().all(|r| r.len() == 2));
    }

    #[test]
    fn a_row_of_the_wrong_length_is_an_error() {
        let mut t = CsvTable::new(&["a", "b"]);
        assert!(t.row(["only one"]).is_err());
    }
}

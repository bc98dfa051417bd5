//! Result tables: CSV and JSON lines.

//! Rendering: text tables, JSON, CSV and figures. No maths here.

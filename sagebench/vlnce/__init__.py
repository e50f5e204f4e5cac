"""VLN-CE / habitat export: R2R-style episodes in habitat's Y-up frame, their vocabulary, scene GLBs."""

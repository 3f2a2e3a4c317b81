"""Stage 1, the language: `.mbs` text to a `ModelSpec` of expression trees (`parse`, `spec`, the
grammar), and what evaluates those trees with units (`units`, `evaluate`)."""

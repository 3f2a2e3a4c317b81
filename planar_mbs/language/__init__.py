"""Stage 1, the language: `.mbs` text to a `ModelSpec` of expression trees (`parse`, `spec`, the
grammar), and what evaluates them with units (`units`, `evaluate`), compiles loads and motions into
programs (`expressions`) and reads tables (`tables`)."""

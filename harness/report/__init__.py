"""The pages made from the committed results (`python -m harness docs`): docs/findings.md,
the README's headline section and docs/performance.md's figures; their sentences about the
shipped scenarios and sweeps come from the findings files beside those."""

"""The built-in part kinds the planner places around the seated lens stack, one per module, each
registered in `cad.stages.PART_KINDS` as a plug-in kind is: `hood` (the hood and every vane) and
`housing` (the detector housing and its rear baffle)."""

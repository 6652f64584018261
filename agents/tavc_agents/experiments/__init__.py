"""Running experiments: one trial (`runner`), allocators by name (`registry`), many trials in
parallel and resumable (`sweep`), and the TAVC model measured by simulation (`estimation`)."""

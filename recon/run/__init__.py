"""Running a reconstruction: its options, the stages in order with what each depends on, the scene folder it writes."""

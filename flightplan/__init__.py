"""flightplan: geodesy, circular-orbit planning and Litchi Mission Hub CSV export."""

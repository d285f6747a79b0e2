"""Studies, reproductions and test beds: not library API."""

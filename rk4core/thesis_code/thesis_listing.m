function code = thesis_listing(file, first, stop_before, edits)
% THESIS_LISTING  Lines of a transcribed thesis program, with a driver's edits,
% as one string for eval.
%
%   code = thesis_listing(FILE, FIRST, STOP_BEFORE, EDITS)
%
%   FILE         a transcription in this directory (code01_ode45.m, ...).
%   FIRST        text of the first line to run; STOP_BEFORE: text of the
%                first line not to run. Lines are compared without leading
%                and trailing blanks; each must occur exactly once in FILE.
%   EDITS        K x 3 cell {from, to, replacement}: the printed lines
%                FROM .. TO (inclusive; TO = '' means FROM alone) are
%                replaced by REPLACEMENT (a string, may hold newlines;
%                '' drops them). FROM must occur exactly once between FIRST
%                and STOP_BEFORE, TO at or after it; anything else is an error,
%                so a driver never runs a listing it does not match.
%
% Every other printed line between FIRST and STOP_BEFORE runs as printed.
  text = strrep(fileread(file), sprintf('\r'), '');
  lines = strsplit(text, sprintf('\n'));
  trimmed = strtrim(lines);
  i0 = unique_line(trimmed, first, 1, numel(lines), file);
  i1 = unique_line(trimmed, stop_before, 1, numel(lines), file);
  if i1 <= i0
    error('thesis_listing: in %s, "%s" is not after "%s"', file, stop_before, first);
  end
  keep = lines(i0:i1-1);
  kt = trimmed(i0:i1-1);
  out = keep;
  done = false(size(keep));
  for e = 1:rows(edits)
    a = unique_line(kt, edits{e,1}, 1, numel(kt), file);
    if isempty(edits{e,2})
      b = a;
    else
      b = find(strcmp(kt(a:end), strtrim(edits{e,2})), 1) + a - 1;
      if isempty(b)
        error('thesis_listing: in %s, no line "%s" after "%s"', file, edits{e,2}, edits{e,1});
      end
    end
    if any(done(a:b))
      error('thesis_listing: in %s, edits overlap at "%s"', file, edits{e,1});
    end
    done(a:b) = true;
    out{a} = edits{e,3};
    out(a+1:b) = {[]};
  end
  out = out(~cellfun(@(c) isnumeric(c) && isempty(c), out));
  code = strjoin(out, sprintf('\n'));
end

function i = unique_line(trimmed, line, lo, hi, file)
  hits = find(strcmp(trimmed(lo:hi), strtrim(line))) + lo - 1;
  if numel(hits) ~= 1
    error('thesis_listing: %s has %d lines "%s" where the driver needs exactly one', ...
          file, numel(hits), strtrim(line));
  end
  i = hits;
end
